// The core evaluation: any stack of the standard rows (cpp/core_rows.hpp) with joint springs and dampers, the
// Baumgarte corrector and a KKT solve that survives rank loss (docs/mathematics.md eq. 3), on any joint types
// (free flyers and balls: the step loop integrates on the configuration group).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core_rows.hpp"
#include "grasp_forces.hpp"
#include "kernels.hpp"
#include "kkt_solve.hpp"

namespace pinstab {

// pinstab.forces.joint_spring.JointSpring in joint form: tau[dofs] = -k (q[q_index] - reference) - c v[dofs] on a
// 1-DOF joint; -c v[dofs] (damping only) on a multi-DOF one (q_index < 0).
struct JointSpringSpec {
  VectorXi dofs;
  int q_index = -1;
  double stiffness = 0.0, reference = 0.0, damping = 0.0;
};

// Adds the springs' generalized forces [N, N m] at (q, v) to force.
void add_joint_springs(const std::vector<JointSpringSpec>& springs, const VectorXd& q, const VectorXd& v,
                       Eigen::Ref<VectorXd> force);

// The force elements the core computes: joint springs, grasp holds, constant wrenches.
struct CoreForces {
  std::vector<JointSpringSpec> springs;
  std::vector<HoldSpec> holds;
  std::vector<WrenchSpec> wrenches;
};

// Baumgarte's term per row, -Kd rate - Kp phi with Kd on holonomic rows and Kd / 2 on nonholonomic ones
// (pinstab.stabilizers.baumgarte calls it): phi [m or rad], rate = G v + g_t [m/s or rad/s], Kp [1/s^2], Kd [1/s].
VectorXd baumgarte_term(double kp, double kd, const Mask& holonomic, const VectorXd& phi, const VectorXd& rate);
// Its velocity gain per row [1/s]: Kd on holonomic rows, Kd / 2 on nonholonomic ones.
Eigen::ArrayXd baumgarte_velocity_gains(double kd, const Mask& holonomic);

// pinstab.scene.GravityTilt: gravity g(t) = R(axis, -(start + rate t)) g0 [m/s^2] (rate [rad/s], start [rad]).
struct GravityTilt {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ(), gravity0 = Eigen::Vector3d::Zero();
  double rate = 0.0, start = 0.0;
  Eigen::Vector3d gravity(double t) const;
};


// What Python computes at each evaluation: the rows of the blocks without compiled rows and the forces of the elements
// without a compiled form (pinstab.paths.core.PythonPart), and the limits of the blocks whose forces have them.
class PythonPart {
 public:
  virtual ~PythonPart() = default;
  // At (t, q, v): the Python blocks' stacked G, phi, g_t and gamma0 (rows in the kernel's order of those blocks)
  // into the given arrays (sized), and the Python forces added to force; false: the evaluation is not to be used.
  virtual bool evaluate(double t, const VectorXd& q, const VectorXd& v, Eigen::MatrixXd& jacobian, VectorXd& phi,
                        VectorXd& time_term, VectorXd& drift, VectorXd& force) = 0;
  // Whether the multipliers (every row) keep the Python blocks' force limits at t.
  virtual bool holds(double t, const VectorXd& multipliers) = 0;
};

// M a + h = tau + forces + G^T lambda, G a = -gamma0 - Kd (G v + g_t) - Kp phi (Kd / 2 on nonholonomic rows), under
// gravity that tilts in time when `tilt` is given.
class CoreKernel : public Kernel {
 public:
  CoreKernel(const pinocchio::Model& model, std::vector<RowBlock> blocks, CoreForces forces, double kp, double kd,
             CoreSolve solve, std::optional<GravityTilt> tilt, std::shared_ptr<PythonPart> python);
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                    VectorXd& a) override;
  int nv() const override { return model_.nv; }
  const pinocchio::Model* group() const override { return &model_; }
  // the last evaluation's multipliers [N, N m] (the rows' order)
  const VectorXd& multipliers() const { return multipliers_; }
  // the largest relative primal residual of the evaluations used
  double worst_residual() const { return worst_residual_; }
  // evaluations by how they were solved: "cholesky", "pseudo-inverse"; not used: "... not accepted", "... outside
  // a contact's limits", "hold outside its cones"
  const std::map<std::string, long>& status_counts() const { return status_counts_; }

 private:
  bool solve(const VectorXd& rhs);
  bool inside_limits() const;

  pinocchio::Model model_;
  pinocchio::Data data_;
  std::vector<RowBlock> blocks_;
  std::vector<int> offsets_;
  CoreForces forces_;
  std::optional<GravityTilt> tilt_;
  std::shared_ptr<PythonPart> python_;
  int python_rows_ = 0;
  Eigen::MatrixXd python_jacobian_;
  VectorXd python_phi_, python_time_term_, python_drift_;
  double kp_, kd_;
  CoreSolve settings_;
  int rows_;
  double worst_residual_ = 0.0;
  std::map<std::string, long> status_counts_;
  Eigen::MatrixXd jacobian_;
  VectorXd phi_, time_term_, drift_, force_, multipliers_, acceleration_;
  Mask holonomic_;
  KktSolve kkt_;
};

}  // namespace pinstab
