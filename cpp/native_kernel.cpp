#include "native_kernel.hpp"

namespace pinstab {

NativeKernel::NativeKernel(const pinocchio::Model& model, const std::vector<ClosureSpec>& closures, double kp,
                           double kd, double mu)
    : model_(model), data_(model_), settings_(1e-14, 1e-12, mu, 50) {
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

bool NativeKernel::acceleration(double, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) {
  a = pinocchio::constraintDynamics(model_, data_, q, v, tau, models_, datas_, settings_);
  return true;
}

}  // namespace pinstab
