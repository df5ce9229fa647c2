// The equality KKT solve of pinstab's constrained dynamics, M a = f + G^T lambda, G a = rhs (docs/mathematics.md
// eq. 4-5): the core kernel's, and the general path's direct solve (pinstab.solvers.proxsuite_.direct_solve).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "kernels.hpp"

namespace pinstab {

// The solve's settings: Cholesky of the Delassus matrix D = G M^-1 G^T where its smallest pivot^2 is at least
// direct_pivot times its largest diagonal entry (pinstab.solvers.proxsuite_.DIRECT_PIVOT); else (redundant or nearly
// dependent rows) its pseudo-inverse, eigenvalues at most cutoff times the largest left out: the least-norm
// multipliers and the least-squares accelerations of rows the mechanism can hardly tell apart. An evaluation whose
// relative primal residual (pinstab.solvers.base.primal_residual) is above accepted is not to be used.
// margin_slack: the fingertip contacts' limits hold above -margin_slack (1 + the largest |component|)
// (pinstab.contact.models.MARGIN_SLACK); an evaluation whose multipliers leave them is not to be used.
struct CoreSolve {
  double direct_pivot = 1e-8, cutoff = 1e-12, accepted = 1e-8, margin_slack = 1e-9;
};

// The pseudo-inverse D^+ of a Delassus matrix D = G M^-1 G^T (symmetric positive semi-definite, r x r) from its
// eigen-decomposition, eigenvalues at most cutoff times the largest left out (for such a D: numpy.linalg.pinv's rule
// with rcond = cutoff, its singular values being its eigenvalues). The one pseudo-inverse of the core solve (KktSolve)
// and the servo solve (ServoParts, cpp/servo_kernel.hpp).
class DelassusPseudoInverse {
 public:
  // false: the decomposition failed (D not finite); D^+ is then NaN
  bool compute(const Eigen::MatrixXd& delassus, double cutoff);
  // D^+ x for a vector (r) or a matrix (r x k) x
  VectorXd apply(const VectorXd& x) const;
  Eigen::MatrixXd apply(const Eigen::MatrixXd& x) const;

 private:
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> spectrum_;
  VectorXd kept_;  // 1 / eigenvalue where kept, else 0
};

// How a solve ended: by Cholesky factors (direct); rows dependent by the direct test and no pseudo-inverse asked
// (dependent); by the pseudo-inverse (pseudo_inverse), or its residual above `accepted` (not_accepted); M not positive
// definite or a result not finite (failed).
enum class KktOutcome { direct, dependent, pseudo_inverse, not_accepted, failed };

class KktSolve {
 public:
  // a [m/s^2, rad/s^2] and lambda [N, N m] of M a = force + G^T lambda, G a = rhs (M symmetric, both triangles set)
  KktOutcome solve(const Eigen::MatrixXd& mass, const VectorXd& force, const Eigen::MatrixXd& jacobian,
                   const VectorXd& rhs, const CoreSolve& settings, bool pseudo_inverse);
  const VectorXd& acceleration() const { return acceleration_; }
  const VectorXd& multipliers() const { return multipliers_; }
  // the relative primal residual of the last direct or pseudo-inverse solve
  double residual() const { return residual_; }

 private:
  // From multipliers_ (lambda0 = D^-1 demand): a0 = M^-1 (f + G^T lambda0), then one step of iterative refinement,
  // lambda = lambda0 + D^-1 (rhs - G a0) and a = M^-1 (f + G^T lambda), `inverse` applying D^-1 (or its
  // pseudo-inverse). Forming D = G M^-1 G^T squares the rows' condition number; the step measures the miss with G
  // itself, which near a singular configuration (D's eigenvalues 1e-9 of its largest) takes a from 1e-9 to 1e-12 of
  // the exact solution of the KKT system (benchmarks/core_equality.py).
  template <typename Inverse>
  void refine(const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const Inverse& inverse);

  Eigen::LLT<Eigen::MatrixXd> mass_, inner_;
  DelassusPseudoInverse pseudo_inverse_;
  Eigen::MatrixXd spread_, delassus_;
  VectorXd free_, acceleration_, multipliers_;
  double residual_ = 0.0;
};

}  // namespace pinstab
