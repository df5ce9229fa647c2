// The core evaluation: any stack of the standard rows (cpp/core_rows.hpp) with joint springs and dampers, a
// stabilization term of the form -K rate - S phi (Baumgarte's, Mukharlyamov's kinematic one, held or not) and a KKT
// solve that survives rank loss (docs/mathematics.md eq. 3), on any joint types (free flyers and balls: the step loop
// integrates on the configuration group).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "contact_modes.hpp"
#include "core_rows.hpp"
#include "force_elements.hpp"
#include "grasp_forces.hpp"
#include "inertial_term.hpp"
#include "kernels.hpp"
#include "kkt_solve.hpp"
#include "targets.hpp"

namespace pinstab {

// The force elements the core computes: those without rows (cpp/force_elements.hpp) and grasp holds (their torques
// read the core's constraint Jacobian).
struct CoreForces : ForceElements {
  std::vector<HoldSpec> holds;
};

// The stabilization term per row, -K rate - S phi (docs/mathematics.md section 3; pinstab.stabilizers.baumgarte and
// .mukharlyamov call it): phi [m or rad] (zero on nonholonomic rows), rate = G v + g_t [m/s or rad/s], the stiffness S
// [1/s^2], the velocity gains K per row [1/s].
VectorXd stabilization_term(double stiffness, const Eigen::ArrayXd& velocity_gains, const VectorXd& phi,
                            const VectorXd& rate);
// Baumgarte's velocity gain per row [1/s]: Kd on holonomic rows, Kd / 2 on nonholonomic ones.
Eigen::ArrayXd baumgarte_velocity_gains(double kd, const Mask& holonomic);

// The core's stabilization term (pinstab.stabilizers.base.CoreTerm): S [1/s^2], K per row [1/s], and whether the term
// is computed at a step's first stage (stage 0) and held over its other stages; with `inertial` (Mukharlyamov's
// inertial variant, cpp/inertial_term.hpp) S and K are matrices that follow the configuration, and stiffness and
// velocity_gains are not read.
struct CoreTerm {
  double stiffness = 0.0;
  Eigen::ArrayXd velocity_gains;
  bool held = false;
  std::optional<InertialGains> inertial;
};

// pinstab.scene.GravityTilt: gravity g(t) = R(axis, -angle(t)) g0 [m/s^2], angle(t) = start + rate t [rad] (rate
// [rad/s]) until it reaches stop [rad] (infinite: it turns on), from when on it stays at stop.
struct GravityTilt {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ(), gravity0 = Eigen::Vector3d::Zero();
  double rate = 0.0, start = 0.0, stop = std::numeric_limits<double>::infinity();
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

// M a + h = tau + forces + G^T lambda, G a = -gamma0 - K (G v + g_t) - S phi (the term held from stage 0 over a step's
// other stages when term.held), under gravity that tilts in time when `tilt` is given. An inertial term needs every
// row compiled (no Python part: std::invalid_argument).
class CoreKernel : public Kernel {
 public:
  CoreKernel(const pinocchio::Model& model, std::vector<RowBlock> blocks, CoreForces forces, CoreTerm term,
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
  // a contact's limits", "hold outside its cones", "spring-damper without a direction"
  const std::map<std::string, long>& status_counts() const { return status_counts_; }
  // the term held over the step (computed at its last stage-0 evaluation; none before one, or after a stage-0
  // evaluation stopped before its rows: the general path's is held then) [m/s^2 or rad/s^2]
  const std::optional<VectorXd>& held_term() const { return held_; }
  // what the projections over its rows read (cpp/projection.hpp CoreProjection): the model, the blocks, the Python part
  const pinocchio::Model& model() const { return model_; }
  const std::vector<RowBlock>& blocks() const { return blocks_; }
  const std::shared_ptr<PythonPart>& python() const { return python_; }
  // Plane contacts in given modes (cpp/contact_modes.hpp) solved in place of the KKT solve, the rows held as
  // bilateral ones (pinstab.solvers.core_modes); none: the KKT solve. The multipliers are then the rows' reactions.
  void set_contacts(std::optional<ContactModes> contacts) { contacts_ = std::move(contacts); }
  ContactModes* contacts() { return contacts_ ? &*contacts_ : nullptr; }

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
  CoreTerm term_;
  std::optional<InertialPass> inertial_;
  std::optional<VectorXd> held_;
  VectorXd term_value_;
  CoreSolve settings_;
  int rows_;
  double worst_residual_ = 0.0;
  std::map<std::string, long> status_counts_;
  Eigen::MatrixXd jacobian_;
  VectorXd phi_, time_term_, drift_, force_, multipliers_, acceleration_;
  KktSolve kkt_;
  std::optional<ContactModes> contacts_;
};

}  // namespace pinstab
