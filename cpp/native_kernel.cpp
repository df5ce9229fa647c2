#include "native_kernel.hpp"

#include "stabilization.hpp"

#include <cmath>
#include <limits>

#include <pinocchio/constraints.hpp>

namespace pinstab {

NativeKernel::NativeKernel(const pinocchio::Model& model, const std::vector<ClosureSpec>& closures, double kp,
                           double kd, const pinocchio::ProximalSettings& settings)
    : model_(model), data_(light_data(model_)), settings_(settings), kp_(kp), kd_(kd) {
  for (const ClosureSpec& closure : closures) {
    pinocchio::RigidConstraintModel constraint(pinocchio::CONTACT_3D, model_, closure.joint1,
                                               pinocchio::SE3(closure.placement1), closure.joint2,
                                               pinocchio::SE3(closure.placement2), pinocchio::LOCAL_WORLD_ALIGNED);
    constraint.baumgarte_corrector_parameters() = pinocchio::BaumgarteCorrectorParametersTpl<double>(kp, kd);
    models_.push_back(constraint);
    datas_.push_back(pinocchio::RigidConstraintData(constraint));
  }
  pinocchio::initConstraintDynamics(model_, data_, models_, datas_);
}

bool NativeKernel::acceleration(int, double, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                                VectorXd& a) {
  a = pinocchio::constraintDynamics(model_, data_, q, v, tau, models_, datas_, settings_);
  return true;
}

double native_residual(const pinocchio::Model& model, pinocchio::Data& data,
                       const pinocchio::RigidConstraintModelVector& models, pinocchio::RigidConstraintDataVector& datas,
                       const Eigen::MatrixXd& rows, double kp, double kd, const VectorXd& v, const VectorXd& a) {
  if (datas.empty()) return 0.0;  // no closures: nothing to miss
  Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(rows.cols(), model.nv);
  pinocchio::getConstraintsJacobian(model, data, models, datas, jacobian);
  VectorXd phi(rows.cols()), drift(rows.cols());
  for (size_t c = 0; c < datas.size(); ++c) {  // phi and gamma0, contact by contact, world axes
    const pinocchio::RigidConstraintData& contact = datas[c];
    phi.segment<3>(3 * c) = contact.oMc1.translation() - contact.oMc2.translation();
    drift.segment<3>(3 * c) =
        contact.contact1_acceleration_drift.linear() - contact.contact2_acceleration_drift.linear();
  }
  const VectorXd rate = jacobian * v;
  const VectorXd rhs = rows * (-drift + stabilization_law(kp, kd, rate, phi));
  // the free force tau - h is not at hand (the check follows a solve it is not given tau of): no natural scale
  const double residual = primal_residual(rows * jacobian, a, rhs, VectorXd::Zero(model.nv), data.M.diagonal());
  return std::isfinite(residual) ? residual : std::numeric_limits<double>::quiet_NaN();
}

std::pair<RowMatrix, VectorXd> NativeKernel::multipliers(const RowMatrix& qs, const RowMatrix& vs, const VectorXd& tau,
                                                        const Eigen::MatrixXd& rows) {
  const long n = qs.rows();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  RowMatrix forces = RowMatrix::Constant(n, rows.rows(), nan);
  VectorXd residuals = VectorXd::Constant(n, nan);
  for (long k = 0; k < n; ++k) {
    if (!qs.row(k).allFinite() || !vs.row(k).allFinite()) continue;
    const VectorXd v = vs.row(k).transpose();
    const VectorXd a = pinocchio::constraintDynamics(model_, data_, qs.row(k).transpose(), v, tau, models_, datas_,
                                                     settings_);
    forces.row(k) = (rows * data_.lambda_c).transpose();
    residuals(k) = native_residual(model_, data_, models_, datas_, rows, kp_, kd_, v, a);
  }
  return {forces, residuals};
}

}  // namespace pinstab
