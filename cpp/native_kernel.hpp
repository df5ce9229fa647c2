#pragma once

#include <utility>

#include <pinocchio/algorithm/constrained-dynamics.hpp>
#include <pinocchio/algorithm/proximal.hpp>

#include "force_elements.hpp"
#include "kernels.hpp"

namespace pinstab {

// [rad or m] the step of NativeKernel::derivatives' central differences in q where Pinocchio's are not had
constexpr double kAccelerationDifferenceStep = 1e-6;

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

// pinstab.paths.native.NativeDynamics compiled: Pinocchio's constraintDynamics with the Baumgarte corrector, under
// tau plus the scene's force elements that read no constraint rows (cpp/force_elements.hpp).
class NativeKernel : public Kernel {
 public:
  // settings: the proximal solve's (absolute and relative accuracy, mu, iterations), NativeDynamics.settings
  NativeKernel(const pinocchio::Model& model, const std::vector<ClosureSpec>& closures, double kp, double kd,
               const pinocchio::ProximalSettings& settings, ForceElements elements = ForceElements());
  // false where an element refuses the state (a spring-damper whose points coincide): Python's evaluation says why
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                    VectorXd& a) override;
  int nv() const override { return model_.nv; }
  // The Newton iteration's Jacobians (Kernel::jacobian): the analytic ones of derivatives().
  bool jacobian(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, Eigen::MatrixXd& dadq,
                Eigen::MatrixXd& dadv) override {
    return derivatives(stage, t, q, v, tau, dadq, dadv);
  }
  // The Jacobians of the acceleration at (t, q, v) under tau (with the elements' forces): dadq [1/s^2] against
  // q (+) dq (dq in the tangent space at q), dadv [1/s], nv x nv each. Pinocchio's analytic derivatives of the
  // dynamics (computeABADerivatives without closures; with them computeConstraintDynamicsDerivatives, whose
  // constraint acceleration carries the corrector's Kp and Kd terms) plus the elements' own derivatives
  // (force_element_derivatives) through d a / d tau (M^-1, or Pinocchio's ddq_dtau with closures). Where a closure
  // joins two bodies, Pinocchio 4.1's d a / d q misses terms (the four-bar's crank column is off by 50 /s^2 of 36
  // at Kp = Kd = 0; closures to the world match differences to 1e-10): dadq is then central differences of this
  // kernel's acceleration over pinocchio::integrate steps of kAccelerationDifferenceStep (2 nv evaluations), dadv
  // still analytic. False where an element refuses the state or a result is not finite.
  bool derivatives(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                   Eigen::MatrixXd& dadq, Eigen::MatrixXd& dadv);
  // At each sample (time ts(k) [s], rows of qs, vs) under tau and the elements: the multipliers rows * lambda_c [N]
  // (rows: Pinocchio's contact rows to the closures' rows) and the solve's relative residual (native_residual); NaN
  // where q or v is not finite or an element refuses the state.
  std::pair<RowMatrix, VectorXd> multipliers(const VectorXd& ts, const RowMatrix& qs, const RowMatrix& vs,
                                             const VectorXd& tau, const Eigen::MatrixXd& rows);

 private:
  pinocchio::Model model_;
  pinocchio::Data data_;
  pinocchio::RigidConstraintModelVector models_;
  pinocchio::RigidConstraintDataVector datas_;
  pinocchio::ProximalSettings settings_;
  double kp_, kd_;
  bool two_bodies_ = false;  // some closure joins two bodies (not a body and the world)
  ForceElements elements_;
  VectorXd force_;
  Eigen::MatrixXd force_dq_, force_dv_;

  // force_ = tau plus the elements' forces at (t, q, v) (a kinematics pass in data_ where they read one); false as
  // add_force_elements
  bool applied_force(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau);
};

}  // namespace pinstab
