#include "native_kernel.hpp"

#include "group.hpp"

#include "stabilization.hpp"

#include <cmath>
#include <limits>

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/constrained-dynamics-derivatives.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/constraints.hpp>

namespace pinstab {

NativeKernel::NativeKernel(const pinocchio::Model& model, const std::vector<ClosureSpec>& closures, double kp,
                           double kd, const pinocchio::ProximalSettings& settings, ForceElements elements)
    : model_(model),
      data_(light_data(model_)),
      settings_(settings),
      kp_(kp),
      kd_(kd),
      elements_(std::move(elements)) {
  for (const ClosureSpec& closure : closures) {
    pinocchio::RigidConstraintModel constraint(pinocchio::CONTACT_3D, model_, closure.joint1,
                                               pinocchio::SE3(closure.placement1), closure.joint2,
                                               pinocchio::SE3(closure.placement2), pinocchio::LOCAL_WORLD_ALIGNED);
    constraint.baumgarte_corrector_parameters() = pinocchio::BaumgarteCorrectorParametersTpl<double>(kp, kd);
    models_.push_back(constraint);
    two_bodies_ = two_bodies_ || (closure.joint1 != 0 && closure.joint2 != 0);
    datas_.push_back(pinocchio::RigidConstraintData(constraint));
  }
  pinocchio::initConstraintDynamics(model_, data_, models_, datas_);
}

bool NativeKernel::applied_force(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau) {
  force_ = tau;
  if (elements_.kinematic()) {
    pinocchio::computeJointJacobians(model_, data_, q);
    pinocchio::updateFramePlacements(model_, data_);
  }
  return add_force_elements(model_, data_, elements_, t, q, v, force_);
}

bool NativeKernel::acceleration(int, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                                VectorXd& a) {
  if (elements_.empty()) {
    a = pinocchio::constraintDynamics(model_, data_, q, v, tau, models_, datas_, settings_);
    return true;
  }
  if (!applied_force(t, q, v, tau)) return false;
  a = pinocchio::constraintDynamics(model_, data_, q, v, force_, models_, datas_, settings_);
  return true;
}

bool NativeKernel::derivatives(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                               Eigen::MatrixXd& dadq, Eigen::MatrixXd& dadv) {
  const auto acceleration_at = [&](const VectorXd& shifted, VectorXd& a) {
    return acceleration(stage, t, shifted, v, tau, a);
  };
  if (two_bodies_ && !tangent_differences(model_, q, kAccelerationDifferenceStep, acceleration_at, dadq)) return false;
  if (!force_element_derivatives(model_, data_, elements_, q, v, force_dq_, force_dv_)) return false;
  if (!applied_force(t, q, v, tau)) return false;
  if (models_.empty()) {  // no closures: the articulated-body algorithm's derivatives, d a / d tau = M^-1
    pinocchio::computeABADerivatives(model_, data_, q, v, force_);
  } else {
    pinocchio::constraintDynamics(model_, data_, q, v, force_, models_, datas_, settings_);
    pinocchio::computeConstraintDynamicsDerivatives(model_, data_, models_, datas_, settings_);
  }
  if (!two_bodies_) dadq = data_.ddq_dq;
  dadv = data_.ddq_dv;
  if (!elements_.empty()) {  // the elements' forces through d a / d tau
    const auto through = [&](const auto& dadtau) {
      if (!two_bodies_) dadq.noalias() += dadtau * force_dq_;
      dadv.noalias() += dadtau * force_dv_;
    };
    if (models_.empty()) {
      through(data_.Minv);
    } else {
      through(data_.ddq_dtau);
    }
  }
  return dadq.allFinite() && dadv.allFinite();
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

std::pair<RowMatrix, VectorXd> NativeKernel::multipliers(const VectorXd& ts, const RowMatrix& qs, const RowMatrix& vs,
                                                        const VectorXd& tau, const Eigen::MatrixXd& rows) {
  const long n = qs.rows();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  RowMatrix forces = RowMatrix::Constant(n, rows.rows(), nan);
  VectorXd residuals = VectorXd::Constant(n, nan);
  for (long k = 0; k < n; ++k) {
    if (!qs.row(k).allFinite() || !vs.row(k).allFinite()) continue;
    const VectorXd q = qs.row(k).transpose(), v = vs.row(k).transpose();
    VectorXd a(model_.nv);
    if (!acceleration(0, ts(k), q, v, tau, a)) continue;
    forces.row(k) = (rows * data_.lambda_c).transpose();
    residuals(k) = native_residual(model_, data_, models_, datas_, rows, kp_, kd_, v, a);
  }
  return {forces, residuals};
}

}  // namespace pinstab
