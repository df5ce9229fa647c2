#include "kkt_solve.hpp"

#include <limits>
#include <vector>

#include <pinocchio/algorithm/cholesky.hpp>

namespace pinstab {

namespace {

constexpr Eigen::Index SPARSE_MIN_ROWS = 16;  // below: the dense Cholesky of D costs a few microseconds
constexpr double SPARSE_MAX_DENSITY = 0.25;    // of D's entries not zero

}  // namespace

bool sparse_delassus_pays(Eigen::Index rows, Eigen::Index nonzeros) {
  return rows >= SPARSE_MIN_ROWS && static_cast<double>(nonzeros) <= SPARSE_MAX_DENSITY * rows * rows;
}

Eigen::Index delassus_nonzeros_bound(const pinocchio::Data& data,
                                     const Eigen::SparseMatrix<double, Eigen::RowMajor>& jacobian) {
  const Eigen::Index nv = jacobian.cols();
  std::vector<int> subtree(static_cast<size_t>(nv)), rows_touching(static_cast<size_t>(nv), 0),
      last_row(static_cast<size_t>(nv), -1);
  for (Eigen::Index dof = 0; dof < nv; ++dof) {  // a dof's parent comes before it
    const int parent = data.parents_fromRow[static_cast<size_t>(dof)];
    subtree[static_cast<size_t>(dof)] = parent < 0 ? static_cast<int>(dof) : subtree[static_cast<size_t>(parent)];
  }
  for (int row = 0; row < jacobian.outerSize(); ++row) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(jacobian, row); it; ++it) {
      const size_t root = static_cast<size_t>(subtree[static_cast<size_t>(it.col())]);
      if (last_row[root] == row) continue;
      last_row[root] = row;
      ++rows_touching[root];
    }
  }
  Eigen::Index bound = 0;
  for (const int count : rows_touching) bound += static_cast<Eigen::Index>(count) * count;
  return bound;
}

KktOutcome KktSolve::solve(const Eigen::MatrixXd& mass, const VectorXd& force, const Eigen::MatrixXd& jacobian,
                           const VectorXd& rhs, const CoreSolve& settings, bool pseudo_inverse) {
  residual_ = 0.0;
  sparse_ = false;
  mass_.compute(mass);
  if (mass_.info() != Eigen::Success) return KktOutcome::failed;
  free_ = mass_.solve(force);
  acceleration_ = free_;
  multipliers_.setZero(jacobian.rows());
  if (jacobian.rows() == 0) return acceleration_.allFinite() ? KktOutcome::direct : KktOutcome::failed;
  spread_ = mass_.solve(jacobian.transpose());
  delassus_.noalias() = jacobian * spread_;
  return finish(jacobian, rhs, force, mass.diagonal(), settings, pseudo_inverse);
}

KktOutcome KktSolve::solve(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& force,
                           const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const CoreSolve& settings,
                           bool pseudo_inverse) {
  residual_ = 0.0;
  sparse_ = false;
  const Eigen::Index rows = jacobian.rows();
  if (rows >= SPARSE_MIN_ROWS) sparse_jacobian_ = jacobian.sparseView(1.0, 0.0);  // its entries not zero
  if (rows < SPARSE_MIN_ROWS || !sparse_delassus_pays(rows, delassus_nonzeros_bound(data, sparse_jacobian_))) {
    return solve(data.M, force, jacobian, rhs, settings, pseudo_inverse);
  }
  sparse_ = true;
  pinocchio::cholesky::decompose(model, data);
  if (!(data.D.array() > 0.0).all()) return KktOutcome::failed;  // M not positive definite (or not finite)
  free_ = force;
  pinocchio::cholesky::solve(model, data, free_);
  acceleration_ = free_;
  multipliers_.setZero(rows);
  spread_ = jacobian.transpose();
  pinocchio::cholesky::solve(model, data, spread_);
  delassus_.noalias() = sparse_jacobian_ * spread_;
  sparse_delassus_ = delassus_.sparseView(1.0, 0.0);
  return finish(jacobian, rhs, force, data.M.diagonal(), settings, pseudo_inverse);
}

KktOutcome KktSolve::finish(const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const VectorXd& force,
                            const VectorXd& mass_diagonal, const CoreSolve& settings, bool pseudo_inverse) {
  const VectorXd demand = rhs - jacobian * free_;
  const double largest = delassus_.diagonal().maxCoeff();
  bool factored;
  VectorXd pivots;
  if (sparse_) {
    sparse_inner_.compute(sparse_delassus_);
    factored = sparse_inner_.info() == Eigen::Success;
    if (factored) pivots = sparse_inner_.matrixL().nestedExpression().diagonal();
  } else {
    inner_.compute(delassus_);
    factored = inner_.info() == Eigen::Success;
    if (factored) pivots = inner_.matrixLLT().diagonal();
  }
  if (factored && independent_by_margin(pivots, largest, settings.direct_pivot)) {
    const auto inverse = [this](const VectorXd& x) -> VectorXd {
      return sparse_ ? VectorXd(sparse_inner_.solve(x)) : VectorXd(inner_.solve(x));
    };
    multipliers_ = inverse(demand);
    refine(jacobian, rhs, inverse);
    if (!acceleration_.allFinite()) return KktOutcome::failed;
    residual_ = primal_residual(jacobian, acceleration_, rhs, force, mass_diagonal);
    return KktOutcome::direct;
  }
  if (!pseudo_inverse) return KktOutcome::dependent;
  // redundant or nearly dependent rows: the pseudo-inverse of D, eigenvalues below cutoff times the largest left out
  if (!pseudo_inverse_.compute(delassus_, settings.cutoff)) return KktOutcome::failed;
  const auto pseudo_inverse_of = [this](const VectorXd& x) -> VectorXd { return pseudo_inverse_.apply(x); };
  multipliers_ = pseudo_inverse_of(demand);
  refine(jacobian, rhs, pseudo_inverse_of);
  residual_ = primal_residual(jacobian, acceleration_, rhs, force, mass_diagonal);
  if (!acceleration_.allFinite()) return KktOutcome::failed;
  return residual_ <= settings.accepted ? KktOutcome::pseudo_inverse : KktOutcome::not_accepted;
}

bool DelassusPseudoInverse::compute(const Eigen::MatrixXd& delassus, double cutoff) {
  spectrum_.compute(delassus);
  const VectorXd& values = spectrum_.eigenvalues();  // ascending
  // a 1 x 1 infinite D decomposes "successfully" (eigenvalue inf): its cutoff would keep nothing, D^+ = 0
  if (spectrum_.info() != Eigen::Success || !values.allFinite()) {
    kept_.setConstant(delassus.rows(), std::numeric_limits<double>::quiet_NaN());
    return false;
  }
  if (values.size() == 0) {
    kept_.resize(0);
    return true;
  }
  const double floor = cutoff * values(values.size() - 1);
  kept_ = (values.array() > floor).select(values.array().inverse(), 0.0).matrix();
  return true;
}

VectorXd DelassusPseudoInverse::apply(const VectorXd& x) const {
  return spectrum_.eigenvectors() * (kept_.array() * (spectrum_.eigenvectors().transpose() * x).array()).matrix();
}

Eigen::MatrixXd DelassusPseudoInverse::apply(const Eigen::MatrixXd& x) const {
  return spectrum_.eigenvectors() * (kept_.asDiagonal() * (spectrum_.eigenvectors().transpose() * x));
}

template <typename Inverse>
void KktSolve::refine(const Eigen::MatrixXd& jacobian, const VectorXd& rhs, const Inverse& inverse) {
  acceleration_ = free_ + spread_ * multipliers_;
  multipliers_ += inverse(rhs - jacobian * acceleration_);
  acceleration_ = free_ + spread_ * multipliers_;
}

double primal_residual(const Eigen::MatrixXd& jacobian, const VectorXd& a, const VectorXd& rhs, const VectorXd& force,
                       const VectorXd& mass_diagonal, const Mask& unilateral) {
  VectorXd miss = jacobian * a - rhs;
  if (unilateral.size()) miss = unilateral.select(miss.cwiseMin(0.0), miss);
  const double size = miss.norm();
  if (size == 0.0) return 0.0;
  const double natural = force.norm() / mass_diagonal.minCoeff();
  const double scale = rhs.norm() + jacobian.norm() * (a.norm() + natural);
  return scale > 0.0 ? size / scale : std::numeric_limits<double>::infinity();
}

bool independent_by_margin(const VectorXd& factor_diagonal, double largest, double direct_pivot) {
  if (factor_diagonal.size() == 0) return true;
  const double smallest = factor_diagonal.minCoeff();
  return smallest * smallest >= direct_pivot * largest;
}

}  // namespace pinstab
