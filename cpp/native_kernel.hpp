#pragma once

#include <utility>

#include <pinocchio/algorithm/constrained-dynamics.hpp>
#include <pinocchio/algorithm/proximal.hpp>

#include "kernels.hpp"

namespace pinstab {

// One closure of the native path: a 3-D contact between two joints' frames, in world-aligned axes.
struct ClosureSpec {
  int joint1, joint2;
  Eigen::Matrix4d placement1, placement2;  // homogeneous placements in the joints' frames
};

// The closures' models and datas wrapped by Python's pin.StdVec_RigidConstraintModel / StdVec_RigidConstraintData
// (cpp/python_data.cpp); throws std::invalid_argument for another object. The caller keeps the object alive.
pinocchio::RigidConstraintModelVector& python_constraint_models(PyObject* object);
pinocchio::RigidConstraintDataVector& python_constraint_datas(PyObject* object);

// How far the last constraintDynamics solve in data, datas (of the closures `models`, Kp [1/s^2], Kd [1/s]) misses
// G a + gamma0 = -Kp phi - Kd G v (stabilization_law), relative: primal_residual [-] on the closures' rows (rows:
// Pinocchio's contact rows to them; G = rows times Pinocchio's constraint Jacobian) without the free force's scale,
// |G a - rhs| / (|rhs| + |G|_F |a|), from Pinocchio's constraint Jacobian, contact points and drifts; NaN where it is
// not finite (a miss where the scale is zero) (pinstab.paths.native.NativeDynamics.residual calls it).
double native_residual(const pinocchio::Model& model, pinocchio::Data& data,
                       const pinocchio::RigidConstraintModelVector& models, pinocchio::RigidConstraintDataVector& datas,
                       const Eigen::MatrixXd& rows, double kp, double kd, const VectorXd& v, const VectorXd& a);

// pinstab.paths.native.NativeDynamics compiled: Pinocchio's constraintDynamics with the Baumgarte corrector.
class NativeKernel : public Kernel {
 public:
  // settings: the proximal solve's (absolute and relative accuracy, mu, iterations), NativeDynamics.settings
  NativeKernel(const pinocchio::Model& model, const std::vector<ClosureSpec>& closures, double kp, double kd,
               const pinocchio::ProximalSettings& settings);
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                    VectorXd& a) override;
  int nv() const override { return model_.nv; }
  // At each sample (rows of qs, vs) under tau: the multipliers rows * lambda_c [N] (rows: Pinocchio's contact rows to
  // the closures' rows) and the solve's relative residual (native_residual); NaN where q or v is not finite.
  std::pair<RowMatrix, VectorXd> multipliers(const RowMatrix& qs, const RowMatrix& vs, const VectorXd& tau,
                                             const Eigen::MatrixXd& rows);

 private:
  pinocchio::Model model_;
  pinocchio::Data data_;
  pinocchio::RigidConstraintModelVector models_;
  pinocchio::RigidConstraintDataVector datas_;
  pinocchio::ProximalSettings settings_;
  double kp_, kd_;
};

}  // namespace pinstab
