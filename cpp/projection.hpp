// The post-step corrections of `projection` and `post` (docs/mathematics.md section 3.4): the M-weighted least-change
// correction, the Gauss-Newton position projection with its stopping rule and the velocity projection, once, for every
// projector (pinstab.projection calls them with pinstab's Python projectors; CoreProjection evaluates the core kernel's
// rows in C++), and the correction of each step of the compiled loop on the core path (CoreCorrection).
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include "core_kernel.hpp"
#include "group.hpp"
#include "kkt_solve.hpp"

namespace pinstab {

// -M^-1 G^T (G M^-1 G^T)^+ r [m or rad, m/s or rad/s]: the smallest change in the kinetic metric that removes the
// residual r to first order, D^+ the Delassus matrix's pseudo-inverse (DelassusPseudoInverse, eigenvalues at most
// cutoff times the largest left out), M^-1 G^T from the Cholesky factors of M; factored once for (M, G), applied to
// any residual of the rows.
// Forming D squares the rows' condition: where they are near-singular (cassie's shin and heel-spring triangles near
// alignment: singular values of G L^-T down to 1e-8 of the largest, M = L L^T) D's eigenvalues there fall below the
// cutoff or into D's rounding, and the correction leaves their part of r in place (cassie's kicked start kept a
// velocity residual of 5e-6 m/s; the position projection after a 5 ms step stalled at 3e-8 m). Asked to (`refine`),
// the change is refined once where the residual it leaves, G change + r, is above cutoff times its scale (|r| + |G|
// |change|, max-norms): by the least-norm solution of the square root's rows, -L^-T (G L^-T)^+ (G change + r), its
// pseudo-inverse by the singular value decomposition (Eigen's JacobiSVD, singular values at most cutoff times the
// largest left out), kept where it at least halves that residual (not where the residual is outside the rows' range:
// redundant rows inconsistent beyond rounding). Where the first change leaves rounding the change is D's alone.
class LeastChange {
 public:
  // false: M not positive definite, or M, G or G M^-1 G^T not finite
  bool factor(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, double cutoff);
  // the change for r (rows), refined where `refine` (see above); false (change NaN): not factored, or r or the
  // change not finite
  bool apply(const VectorXd& residual, VectorXd& change, bool refine = false) const;

 private:
  // the refinement of `change` for r (see above): changes it where the square root's solve at least halves the
  // residual it leaves
  void refined(const VectorXd& residual, VectorXd& change) const;

  bool factored_ = false;
  double cutoff_ = 0.0;
  Eigen::MatrixXd jacobian_;  // G
  Eigen::MatrixXd spread_;    // M^-1 G^T
  Eigen::LLT<Eigen::MatrixXd> mass_factors_;
  DelassusPseudoInverse inverse_;
  mutable std::unique_ptr<Eigen::JacobiSVD<Eigen::MatrixXd>> root_;  // of G L^-T, made on the first refinement
};

// LeastChange's factors of (M, G) applied to r once (refined where `refine`).
bool weighted_correction(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, const VectorXd& residual,
                         double cutoff, VectorXd& change, bool refine = false);

// The two projections a correction is made of, on one path (pinstab.projection.Projector).
class Projections {
 public:
  virtual ~Projections() = default;
  // The Gauss-Newton step dq = -M^-1 G^T (G M^-1 G^T)^+ phi at (q, t) and max |phi| over the enforced rows [m or rad]
  // (NaN where not finite); false: the rows are not finite.
  virtual bool position_step(const VectorXd& q, double t, VectorXd& step, double& worst) = 0;
  // v - M^-1 G^T (G M^-1 G^T)^+ (G v + g_t) at (q, t) [m/s or rad/s]; false: not finite.
  virtual bool velocity_projection(const VectorXd& q, const VectorXd& v, double t, VectorXd& projected) = 0;
  // Have both projections refine their least change (LeastChange's `refine`) from now on (on) or not (off); false:
  // these projections cannot (a Python projector's).
  virtual bool refine(bool on) { return false; }
};

// How a correction ended: done; the Gauss-Newton iteration did not converge (its last residual in `worst`); the rows
// or the result not finite.
enum class CorrectionOutcome { done = 0, not_converged = 1, not_finite = 2 };

// The stopping rule of the position projection (pinstab.projection.project_positions): threshold [m or rad] on the
// residual and the last step, floor [m or rad] the residual that is rounding, at most max_iterations steps.
struct PositionRule {
  double threshold = 0.0, floor = 0.0;
  int max_iterations = 20;
};

// Gauss-Newton on phi(q) = 0 from q (q becomes the projected configuration): converged when the last step is below the
// threshold with the residual below it too, or when the residual is below the threshold and at rounding level (floor)
// or the steps stop contracting (by less than CONTRACTION a step). iterations: the steps taken; worst: the last
// residual [m or rad]. Where it does not converge with D's pseudo-inverse alone it starts again from q with the
// projections refining (Projections::refine, where they can), and they stay refining until the next call (the
// velocities of a correction projected the same way); where it converges the steps are D's alone, to the bit.
CorrectionOutcome project_positions(Projections& projections, const Group& group, const PositionRule& rule, double t,
                                    VectorXd& q, int& iterations, double& worst);

// A method's correction: `projection` (post false: the position projection, then the velocities projected at the
// projected q) or `post` (one position step and the velocities projected, both at the uncorrected state; the rule's
// tolerances unused). (q, v) become the corrected state.
CorrectionOutcome correct(Projections& projections, const Group& group, bool post, const PositionRule& rule, double t,
                          VectorXd& q, VectorXd& v, int& iterations, double& worst);

// The projections on the core kernel's rows (its blocks, its Python part's rows), from a kinematics pass and M of its
// own: the position step over the holonomic rows, the velocity projection over every row (the core's rows are
// equalities). The last evaluation (its q and t) and its factors are reused at the same state (a velocity projection
// after the position step there: one factorization where every row is holonomic).
class CoreProjection : public Projections {
 public:
  CoreProjection(const CoreKernel& kernel, double cutoff);
  bool position_step(const VectorXd& q, double t, VectorXd& step, double& worst) override;
  bool velocity_projection(const VectorXd& q, const VectorXd& v, double t, VectorXd& projected) override;
  bool refine(bool on) override {
    refining_ = on;
    return true;
  }
  const pinocchio::Model& model() const { return model_; }

 private:
  // M, G, phi, g_t at (q, t); false: not finite
  bool evaluate(const VectorXd& q, double t);

  pinocchio::Model model_;
  pinocchio::Data data_;
  std::vector<RowBlock> blocks_;
  std::shared_ptr<PythonPart> python_;
  double cutoff_;
  int rows_ = 0, python_rows_ = 0;
  std::vector<int> holonomic_;  // the holonomic rows' indices
  bool evaluated_ = false, finite_ = false, every_row_holonomic_ = true;
  bool enforced_factored_ = false, every_factored_ = false;  // at the last evaluation
  bool refining_ = false;
  LeastChange enforced_, every_;  // the factors of the holonomic rows, of every row
  double t_ = 0.0;
  VectorXd q_;
  Eigen::MatrixXd mass_, jacobian_, python_jacobian_, enforced_jacobian_;
  VectorXd phi_, time_term_, python_phi_, python_time_term_, python_drift_, python_force_, enforced_phi_;
};

// The correction of every step of the compiled loop (fixed_steps, cpp/step_loop.hpp) on the core path: `projection`
// or `post` by `correct` with the core's projections (held: the caller keeps them alive).
class CoreCorrection : public Corrector {
 public:
  CoreCorrection(CoreProjection& projections, bool post, PositionRule rule)
      : projections_(&projections), group_(&projections.model()), post_(post), rule_(rule) {}
  int correct(double t, VectorXd& q, VectorXd& v) override;

 private:
  CoreProjection* projections_;
  Group group_;
  bool post_;
  PositionRule rule_;
};

}  // namespace pinstab
