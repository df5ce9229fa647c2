// The equality KKT solve of pinstab's constrained dynamics, M a = f + G^T lambda, G a = rhs (docs/mathematics.md
// eq. 4-5): the core kernel's, and the general path's direct solve (pinstab.solvers.proxsuite_.direct_solve).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

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
  // The same with M = data.M of `model` at the state (its upper triangle set), exploiting the structure where D is
  // sparse (sparse_delassus_pays on delassus_nonzeros_bound: a long chain of loops, as the N-four-bar's; not a floating
  // base, whose M^-1 couples every row): M factored along the kinematic tree (Pinocchio's M = U D U^T,
  // cholesky::decompose: no fill-in), D = G (M^-1 G^T) formed from G's entries not zero, and D's Cholesky in sparse
  // storage in its natural order (D's pivots, so the direct test, are the dense Cholesky's); the pseudo-inverse and the
  // refinement as in the dense solve. Elsewhere the dense solve.
  // Decided by measurement (benchmarks/kkt_sparsity.py, figures in docs/guide/benchmarks.md): on the N-four-bar forced
  // onto the core this makes the evaluation about 2x faster at N = 40 and 4x at N = 80 (the dense solve, O(nv^3), was
  // 3/4 and 7/8 of it); on cassie (a floating base: D dense, its redundant rows' eigen-decomposition half the solve)
  // and delta (12 rows, a 3 us solve) no factorization of M or D gains 1.2x, so they keep the dense solve. Eigen's
  // sparse LDL^T of the regularized KKT matrix, refined, is faster still (about 2x on cassie's evaluation, 6x at
  // N = 80) but has no Delassus matrix for the direct test and the pseudo-inverse (a proximal answer on redundant
  // rows), and Pinocchio's ContactCholeskyDecomposition costs more than the whole dense solve at N = 40 and 80.
  KktOutcome solve(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& force,
                   const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const CoreSolve& settings,
                   bool pseudo_inverse);
  const VectorXd& acceleration() const { return acceleration_; }
  const VectorXd& multipliers() const { return multipliers_; }
  // the relative primal residual of the last direct or pseudo-inverse solve
  double residual() const { return residual_; }
  // whether the last solve took the sparse factorization
  bool sparse() const { return sparse_; }

 private:
  using Sparse = Eigen::SparseMatrix<double>;
  // From free_ = M^-1 f, spread_ = M^-1 G^T and delassus_ = G spread_: D's Cholesky (dense, or sparse where
  // sparse_), the direct test, the pseudo-inverse where it fails, the refinement and the residual.
  KktOutcome finish(const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const VectorXd& force,
                    const VectorXd& mass_diagonal, const CoreSolve& settings, bool pseudo_inverse);
  // From multipliers_ (lambda0 = D^-1 demand): a0 = M^-1 (f + G^T lambda0), then one step of iterative refinement,
  // lambda = lambda0 + D^-1 (rhs - G a0) and a = M^-1 (f + G^T lambda), `inverse` applying D^-1 (or its
  // pseudo-inverse). Forming D = G M^-1 G^T squares the rows' condition number; the step measures the miss with G
  // itself, which near a singular configuration (D's eigenvalues 1e-9 of its largest) takes a from 1e-9 to 1e-12 of
  // the exact solution of the KKT system (benchmarks/core_equality.py).
  template <typename Inverse>
  void refine(const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const Inverse& inverse);

  Eigen::LLT<Eigen::MatrixXd> mass_, inner_;
  Eigen::SimplicialLLT<Sparse, Eigen::Lower, Eigen::NaturalOrdering<int>> sparse_inner_;
  DelassusPseudoInverse pseudo_inverse_;
  Eigen::MatrixXd spread_, delassus_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> sparse_jacobian_;
  Sparse sparse_delassus_;
  VectorXd free_, acceleration_, multipliers_;
  double residual_ = 0.0;
  bool sparse_ = false;
};

// Whether the sparse solve pays for a Delassus matrix of `rows` rows with at most `nonzeros` entries not zero: at least
// SPARSE_MIN_ROWS rows, at most SPARSE_MAX_DENSITY of its entries (benchmarks/kkt_sparsity.py).
bool sparse_delassus_pays(Eigen::Index rows, Eigen::Index nonzeros);
// A bound on the entries of D = G M^-1 G^T not zero, from the structure: M^-1 couples only the dofs of one subtree of
// the universe, so D(i, j) is zero unless rows i and j both touch such a subtree (G's entries not zero): the sum over
// those subtrees of the number of rows touching each, squared. One floating base: rows^2 (D dense).
Eigen::Index delassus_nonzeros_bound(const pinocchio::Data& data,
                                     const Eigen::SparseMatrix<double, Eigen::RowMajor>& jacobian);

}  // namespace pinstab
