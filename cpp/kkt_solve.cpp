#include "kkt_solve.hpp"

#include <limits>

namespace pinstab {

KktOutcome KktSolve::solve(const Eigen::MatrixXd& mass, const VectorXd& force, const Eigen::MatrixXd& jacobian,
                           const VectorXd& rhs, const CoreSolve& settings, bool pseudo_inverse) {
  residual_ = 0.0;
  mass_.compute(mass);
  if (mass_.info() != Eigen::Success) return KktOutcome::failed;
  free_ = mass_.solve(force);
  acceleration_ = free_;
  multipliers_.setZero(jacobian.rows());
  if (jacobian.rows() == 0) return acceleration_.allFinite() ? KktOutcome::direct : KktOutcome::failed;
  spread_ = mass_.solve(jacobian.transpose());
  delassus_.noalias() = jacobian * spread_;
  const VectorXd demand = rhs - jacobian * free_;
  const double largest = delassus_.diagonal().maxCoeff();
  inner_.compute(delassus_);
  if (inner_.info() == Eigen::Success &&
      independent_by_margin(inner_.matrixLLT().diagonal(), largest, settings.direct_pivot)) {
    multipliers_ = inner_.solve(demand);
    refine(jacobian, rhs, [this](const VectorXd& miss) -> VectorXd { return inner_.solve(miss); });
    if (!acceleration_.allFinite()) return KktOutcome::failed;
    residual_ = primal_residual(jacobian, acceleration_, rhs, force, mass.diagonal());
    return KktOutcome::direct;
  }
  if (!pseudo_inverse) return KktOutcome::dependent;
  // redundant or nearly dependent rows: the pseudo-inverse of D, eigenvalues below cutoff times the largest left out
  if (!pseudo_inverse_.compute(delassus_, settings.cutoff)) return KktOutcome::failed;
  const auto pseudo_inverse_of = [this](const VectorXd& x) -> VectorXd { return pseudo_inverse_.apply(x); };
  multipliers_ = pseudo_inverse_of(demand);
  refine(jacobian, rhs, pseudo_inverse_of);
  residual_ = primal_residual(jacobian, acceleration_, rhs, force, mass.diagonal());
  if (!acceleration_.allFinite()) return KktOutcome::failed;
  return residual_ <= settings.accepted ? KktOutcome::pseudo_inverse : KktOutcome::not_accepted;
}

bool DelassusPseudoInverse::compute(const Eigen::MatrixXd& delassus, double cutoff) {
  spectrum_.compute(delassus);
  if (spectrum_.info() != Eigen::Success) {
    kept_.setConstant(delassus.rows(), std::numeric_limits<double>::quiet_NaN());
    return false;
  }
  const VectorXd& values = spectrum_.eigenvalues();  // ascending
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
