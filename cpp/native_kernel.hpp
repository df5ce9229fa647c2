#pragma once

#include <pinocchio/algorithm/constrained-dynamics.hpp>
#include <pinocchio/algorithm/proximal.hpp>

#include "kernels.hpp"

namespace pinstab {

// One closure of the native path: a 3-D contact between two joints' frames, in world-aligned axes.
struct ClosureSpec {
  int joint1, joint2;
  Eigen::Matrix4d placement1, placement2;  // homogeneous placements in the joints' frames
};

// pinstab.paths.native.NativeDynamics compiled: Pinocchio's constraintDynamics with the Baumgarte corrector.
class NativeKernel : public Kernel {
 public:
  NativeKernel(const pinocchio::Model& model, const std::vector<ClosureSpec>& closures, double kp, double kd,
               double mu);
  bool acceleration(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) override;
  int nv() const override { return model_.nv; }

 private:
  pinocchio::Model model_;
  pinocchio::Data data_;
  pinocchio::RigidConstraintModelVector models_;
  pinocchio::RigidConstraintDataVector datas_;
  pinocchio::ProximalSettings settings_;
};

}  // namespace pinstab
