// A pinocchio::Data without the second-order derivative tensors (issue 35): pin 4.1's constructor allocates and zeroes
// kinematic_hessians (6 nv^2) and d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq (nv^3 each: 135 MiB and ~50 ms at the
// N-four-bar N = 80), read only by the kinematic Hessians and the second-order RNEA derivatives, which pinstab never
// calls. light_data sets every other member as Pinocchio 4.1's DataTpl(const Model&) does (src/multibody/data.hxx: the
// member list below is its initializer list, the five tensors left empty), and calls the constructor's own private
// index passes. tests/test_light_data.py compares each member a Python pin.Data exposes, and every pass pinstab runs,
// with pin.Data(model).
#include <boost/python.hpp>

#include <algorithm>
#include <stdexcept>

#include "kernels.hpp"

namespace pinstab {
namespace {

using Data = pinocchio::Data;
using IndexPass = void (Data::*)(const pinocchio::Model&);

// The constructor's index passes are private: an explicit instantiation may name a private member (C++ [temp.spec]),
// and the friend it defines hands the member pointer out.
template <typename Tag, IndexPass Pass>
struct Expose {
  friend IndexPass pass(Tag) { return Pass; }
};
struct LastChild {
  friend IndexPass pass(LastChild);
};
struct NvSubtree {
  friend IndexPass pass(NvSubtree);
};
struct ParentsFromRow {
  friend IndexPass pass(ParentsFromRow);
};
struct SupportsFromRow {
  friend IndexPass pass(SupportsFromRow);
};
template struct Expose<LastChild, &Data::computeLastChild>;
template struct Expose<NvSubtree, &Data::computeNvSubtree>;
template struct Expose<ParentsFromRow, &Data::computeParents_fromRow>;
template struct Expose<SupportsFromRow, &Data::computeSupports_fromRow>;

}  // namespace

void fill_light_data(Data& data, const pinocchio::Model& model) {
  using pinocchio::neutral;
  using Scalar = Data::Scalar;
  using VectorXs = Data::VectorXs;
  using MatrixXs = Data::MatrixXs;
  using RowMatrixXs = Data::RowMatrixXs;
  using RowVectorXs = Data::RowVectorXs;
  using Matrix6x = Data::Matrix6x;
  using Matrix3x = Data::Matrix3x;
  using Matrix6 = Data::Matrix6;
  using MatrixXb = Data::MatrixXb;
  using Vector3 = Data::Vector3;
  using Motion = Data::Motion;
  using Force = Data::Force;
  using Inertia = Data::Inertia;
  using SE3 = Data::SE3;
  using BodyRegressorType = Data::BodyRegressorType;
#define PINSTAB_MEMBER(member, ...) data.member = decltype(data.member)(__VA_ARGS__)
  PINSTAB_MEMBER(q_in, neutral(model));
  PINSTAB_MEMBER(v_in, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(a_in, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(tau_in, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(a, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(oa, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(oa_drift, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(oa_augmented, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(a_gf, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(oa_gf, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(v, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(ov, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(f, (std::size_t)model.njoints, Force::Zero());
  PINSTAB_MEMBER(of, (std::size_t)model.njoints, Force::Zero());
  PINSTAB_MEMBER(of_augmented, (std::size_t)model.njoints, Force::Zero());
  PINSTAB_MEMBER(h, (std::size_t)model.njoints, Force::Zero());
  PINSTAB_MEMBER(oh, (std::size_t)model.njoints, Force::Zero());
  PINSTAB_MEMBER(oMi, (std::size_t)model.njoints, SE3::Identity());
  PINSTAB_MEMBER(liMi, (std::size_t)model.njoints, SE3::Identity());
  PINSTAB_MEMBER(tau, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(nle, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(g, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(oMf, (std::size_t)model.nframes, SE3::Identity());
  PINSTAB_MEMBER(Ycrb, (std::size_t)model.njoints, Inertia::Zero());
  PINSTAB_MEMBER(dYcrb, (std::size_t)model.njoints, Inertia::Zero());
  PINSTAB_MEMBER(M, MatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(Minv, MatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(C, MatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(dHdq, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dFdq, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dFdv, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dFda, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(SDinv, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(UDinv, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(IS, MatrixXs::Zero(6, model.nv));
  PINSTAB_MEMBER(vxI, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(Ivx, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(B, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(oinertias, (std::size_t)model.njoints, Inertia::Zero());
  PINSTAB_MEMBER(oYcrb, (std::size_t)model.njoints, Inertia::Zero());
  PINSTAB_MEMBER(doYcrb, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(ddq, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(Yaba, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(oYaba, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(oYaba_augmented, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(oL, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(oK, (std::size_t)model.njoints, Inertia::Matrix6::Zero());
  PINSTAB_MEMBER(u, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(Ag, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dAg, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(hg, Force::Zero());
  PINSTAB_MEMBER(dhg, Force::Zero());
  PINSTAB_MEMBER(Ig, Inertia::Zero());
  PINSTAB_MEMBER(Fcrb, (std::size_t)model.njoints, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(lastChild, (std::size_t)model.njoints, -1);
  PINSTAB_MEMBER(nvSubtree, (std::size_t)model.njoints, 0);
  PINSTAB_MEMBER(start_idx_v_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(end_idx_v_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(idx_vExtended_to_idx_v_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(U, MatrixXs::Identity(model.nv, model.nv));
  PINSTAB_MEMBER(D, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(Dinv, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(tmp, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(parents_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(mimic_parents_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(non_mimic_parents_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(supports_fromRow, (std::size_t)model.nv);
  PINSTAB_MEMBER(nvSubtree_fromRow, (std::size_t)model.nvExtended, -1);
  PINSTAB_MEMBER(J, Matrix6x::Zero(6, model.nvExtended));
  PINSTAB_MEMBER(dJ, Matrix6x::Zero(6, model.nvExtended));
  PINSTAB_MEMBER(ddJ, Matrix6x::Zero(6, model.nvExtended));
  PINSTAB_MEMBER(psid, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(psidd, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dVdq, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dAdq, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dAdv, Matrix6x::Zero(6, model.nv));
  PINSTAB_MEMBER(dtau_dq, RowMatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(dtau_dv, RowMatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(ddq_dq, RowMatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(ddq_dv, RowMatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(ddq_dtau, RowMatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(iMf, (std::size_t)model.njoints, SE3::Identity());
  PINSTAB_MEMBER(com, (std::size_t)model.njoints, Vector3::Zero());
  PINSTAB_MEMBER(vcom, (std::size_t)model.njoints, Vector3::Zero());
  PINSTAB_MEMBER(acom, (std::size_t)model.njoints, Vector3::Zero());
  PINSTAB_MEMBER(mass, (std::size_t)model.njoints, (Scalar)(-1));
  PINSTAB_MEMBER(Jcom, Matrix3x::Zero(3, model.nv));
  PINSTAB_MEMBER(kinetic_energy, Scalar(0));
  PINSTAB_MEMBER(potential_energy, Scalar(0));
  PINSTAB_MEMBER(mechanical_energy, Scalar(0));
  PINSTAB_MEMBER(sDUiJt, MatrixXs::Zero(model.nv, model.nv));
  PINSTAB_MEMBER(torque_residual, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(dq_after, VectorXs::Zero(model.nv));
  PINSTAB_MEMBER(staticRegressor, Matrix3x::Zero(3, 4 * (model.njoints - 1)));
  PINSTAB_MEMBER(bodyRegressor, BodyRegressorType::Zero());
  PINSTAB_MEMBER(jointTorqueRegressor, MatrixXs::Zero(model.nv, 10 * (model.njoints - 1)));
  PINSTAB_MEMBER(kineticEnergyRegressor, RowVectorXs::Zero(10 * (model.njoints - 1)));
  PINSTAB_MEMBER(potentialEnergyRegressor, RowVectorXs::Zero(10 * (model.njoints - 1)));
  PINSTAB_MEMBER(KA, (std::size_t)model.njoints, Matrix6x::Zero(6, 0));
  PINSTAB_MEMBER(LA, (std::size_t)model.njoints, MatrixXs::Zero(0, 0));
  PINSTAB_MEMBER(lA, (std::size_t)model.njoints, VectorXs::Zero(0));
  PINSTAB_MEMBER(lambdaA, (std::size_t)model.njoints, VectorXs::Zero(0));
  PINSTAB_MEMBER(par_cons_ind, (std::size_t)model.njoints, 0);
  PINSTAB_MEMBER(a_bias, (std::size_t)model.njoints, Motion::Zero());
  PINSTAB_MEMBER(KAS, (std::size_t)model.njoints, MatrixXs::Zero(0, 0));
  PINSTAB_MEMBER(extended_motion_propagator, (std::size_t)model.njoints, Matrix6::Zero());
  PINSTAB_MEMBER(extended_motion_propagator2, (std::size_t)model.njoints, Matrix6::Zero());
  PINSTAB_MEMBER(spatial_inv_inertia, (std::size_t)model.njoints, Matrix6::Zero());
  PINSTAB_MEMBER(accumulation_descendant, (std::size_t)model.njoints, 0);
  PINSTAB_MEMBER(accumulation_ancestor, (std::size_t)model.njoints, 0);
  PINSTAB_MEMBER(constraints_supported_dim, (std::size_t)model.njoints, 0);
  PINSTAB_MEMBER(constraints_supported, (std::size_t)model.njoints);
  PINSTAB_MEMBER(constraints_on_joint, (std::size_t)model.njoints);
  PINSTAB_MEMBER(joint_neighbours, (std::size_t)model.njoints);
  PINSTAB_MEMBER(joint_cross_coupling, model.njoints, model.njoints);
  PINSTAB_MEMBER(joint_coupling_info, MatrixXb::Zero(model.njoints, model.njoints));
  PINSTAB_MEMBER(projected_joint_cross_coupling, model.njoints, model.njoints);
  PINSTAB_MEMBER(joint_apparent_inertia,  std::size_t(model.njoints), std::size_t(PINOCCHIO_SQUARE(*std::max_element(model.nvs.begin(), model.nvs.end()))));
#undef PINSTAB_MEMBER
  data.joints.clear();
  data.joints.reserve(static_cast<std::size_t>(model.njoints));
  for (pinocchio::JointIndex i = 0; i < static_cast<pinocchio::JointIndex>(model.njoints); ++i) {
    data.joints.push_back(pinocchio::CreateJointData<Scalar, 0, pinocchio::JointCollectionDefaultTpl>::run(model.joints[i]));
    const auto joint_nv = model.nvs[i];
    data.joint_apparent_inertia.push_back(joint_nv, joint_nv);
    data.joint_apparent_inertia.back().setZero();
  }
  data.joints_augmented = data.joints;
  (data.*pass(LastChild{}))(model);
  (data.*pass(NvSubtree{}))(model);
  (data.*pass(ParentsFromRow{}))(model);
  (data.*pass(SupportsFromRow{}))(model);
  data.a_gf[0] = -model.gravity;
}

Data light_data(const pinocchio::Model& model) {
  Data data;
  fill_light_data(data, model);
  return data;
}

PyObject* new_python_data(PyObject* model) {
  namespace python = boost::python;
  const pinocchio::Model& native = python_model(model);
  python::object data = python::import("pinocchio").attr("Data")();
  void* address = python::converter::get_lvalue_from_python(data.ptr(), python::converter::registered<Data>::converters);
  fill_light_data(*static_cast<Data*>(address), native);
  return python::incref(data.ptr());
}

}  // namespace pinstab
