#include "projection.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>

namespace pinstab {

namespace {

constexpr double NOT_A_NUMBER = std::numeric_limits<double>::quiet_NaN();
// Gauss-Newton steps that shrink less than this per iteration are rounding-dominated
constexpr double CONTRACTION = 0.5;

// max |x| (0 for none; NaN where an entry is), numpy's max(abs(x), initial=0)
double largest(const VectorXd& x) {
  return x.size() == 0 ? 0.0 : x.cwiseAbs().maxCoeff<Eigen::PropagateNaN>();
}

}  // namespace

bool LeastChange::factor(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, double cutoff) {
  factored_ = false;
  root_.reset();
  if (!(mass.allFinite() && jacobian.allFinite())) return false;
  mass_factors_.compute(mass);
  if (mass_factors_.info() != Eigen::Success) return false;
  cutoff_ = cutoff;
  jacobian_ = jacobian;
  spread_ = mass_factors_.solve(jacobian.transpose());  // M^-1 G^T
  if (jacobian.rows()) {
    const Eigen::MatrixXd delassus = jacobian * spread_;
    if (!inverse_.compute(delassus, cutoff)) return false;  // rows that overflow D: not finite
  }
  factored_ = true;
  return true;
}

bool LeastChange::apply(const VectorXd& residual, VectorXd& change, bool refine) const {
  if (!factored_ || !residual.allFinite()) {
    change.setConstant(spread_.rows(), NOT_A_NUMBER);
    return false;
  }
  if (residual.size() == 0) {
    change.setZero(spread_.rows());
    return true;
  }
  change.noalias() = -(spread_ * inverse_.apply(residual));
  if (!change.allFinite()) return false;
  if (refine) refined(residual, change);
  return change.allFinite();
}

void LeastChange::refined(const VectorXd& residual, VectorXd& change) const {
  const VectorXd left = jacobian_ * change + residual;
  const double size = largest(left);
  const double scale = largest(residual) + (jacobian_.cwiseAbs() * change.cwiseAbs()).maxCoeff();
  if (!(size > cutoff_ * scale)) return;
  if (!root_) {  // G L^-T = (L^-1 G^T)^T
    const Eigen::MatrixXd root = mass_factors_.matrixL().solve(jacobian_.transpose()).transpose();
    root_ = std::make_unique<Eigen::JacobiSVD<Eigen::MatrixXd>>(root, Eigen::ComputeThinU | Eigen::ComputeThinV);
    root_->setThreshold(cutoff_);
  }
  const VectorXd refined = change - mass_factors_.matrixU().solve(root_->solve(left));
  if (refined.allFinite() && largest(jacobian_ * refined + residual) <= 0.5 * size) change = refined;
}

bool weighted_correction(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, const VectorXd& residual,
                         double cutoff, VectorXd& change, bool refine) {
  LeastChange least;
  if (!least.factor(mass, jacobian, cutoff)) {
    change.setConstant(mass.rows(), NOT_A_NUMBER);
    return false;
  }
  return least.apply(residual, change, refine);
}

namespace {

// One Gauss-Newton run of project_positions (its stopping rule) from q.
CorrectionOutcome gauss_newton(Projections& projections, const Group& group, const PositionRule& rule, double t,
                               VectorXd& q, int& iterations, double& worst) {
  double previous = std::numeric_limits<double>::infinity();
  VectorXd step;
  for (iterations = 0; iterations <= rule.max_iterations; ++iterations) {
    if (!projections.position_step(q, t, step, worst)) return CorrectionOutcome::not_finite;
    if (!std::isfinite(worst)) break;
    const double size = largest(step);
    if (worst <= rule.threshold && (worst <= rule.floor || size > CONTRACTION * previous)) {
      return CorrectionOutcome::done;
    }
    if (iterations == rule.max_iterations) break;
    q = group.integrate(q, step);
    if (worst <= rule.threshold && size <= rule.threshold) {
      ++iterations;
      return CorrectionOutcome::done;
    }
    previous = size;
  }
  iterations = rule.max_iterations;
  return CorrectionOutcome::not_converged;
}

}  // namespace

CorrectionOutcome project_positions(Projections& projections, const Group& group, const PositionRule& rule, double t,
                                    VectorXd& q, int& iterations, double& worst) {
  projections.refine(false);
  VectorXd moved = q;
  CorrectionOutcome outcome = gauss_newton(projections, group, rule, t, moved, iterations, worst);
  if (outcome == CorrectionOutcome::not_converged && projections.refine(true)) {
    moved = q;
    outcome = gauss_newton(projections, group, rule, t, moved, iterations, worst);
  }
  if (outcome == CorrectionOutcome::done) q = moved;
  return outcome;
}

CorrectionOutcome correct(Projections& projections, const Group& group, bool post, const PositionRule& rule, double t,
                          VectorXd& q, VectorXd& v, int& iterations, double& worst) {
  VectorXd projected;
  if (post) {  // both at the uncorrected state
    projections.refine(false);
    VectorXd step;
    if (!projections.position_step(q, t, step, worst)) return CorrectionOutcome::not_finite;
    if (!projections.velocity_projection(q, v, t, projected)) return CorrectionOutcome::not_finite;
    q = group.integrate(q, step);
    v = projected;
    iterations = 1;
    return CorrectionOutcome::done;
  }
  VectorXd moved = q;
  const CorrectionOutcome outcome = project_positions(projections, group, rule, t, moved, iterations, worst);
  if (outcome != CorrectionOutcome::done) return outcome;
  if (!projections.velocity_projection(moved, v, t, projected)) return CorrectionOutcome::not_finite;
  q = moved;
  v = projected;
  return CorrectionOutcome::done;
}

CoreProjection::CoreProjection(const CoreKernel& kernel, double cutoff)
    : model_(kernel.model()),
      data_(light_data(model_)),
      blocks_(kernel.blocks()),
      python_(kernel.python()),
      cutoff_(cutoff) {
  for (const RowBlock& block : blocks_) {
    for (int row = 0; row < block.rows(); ++row) {
      if (block.holonomic) holonomic_.push_back(rows_ + row);
    }
    every_row_holonomic_ = every_row_holonomic_ && block.holonomic;
    rows_ += block.rows();
    if (block.kind == RowKind::python) python_rows_ += block.rows();
  }
  jacobian_.setZero(rows_, model_.nv);
  phi_.setZero(rows_);
  time_term_.setZero(rows_);
  python_jacobian_.setZero(python_rows_, model_.nv);
  python_phi_.setZero(python_rows_);
  python_time_term_.setZero(python_rows_);
  python_drift_.setZero(python_rows_);
}

bool CoreProjection::evaluate(const VectorXd& q, double t) {
  if (evaluated_ && t == t_ && q.size() == q_.size() && q == q_) return finite_;
  evaluated_ = true, finite_ = false, q_ = q, t_ = t;
  enforced_factored_ = every_factored_ = false;
  // M first (crba passes its own kinematics), then the placements and Jacobians the rows read (pinstab's
  // Kinematics.update_jacobians)
  pinocchio::crba(model_, data_, q);
  mass_ = data_.M;
  mass_.triangularView<Eigen::StrictlyLower>() = mass_.transpose().triangularView<Eigen::StrictlyLower>();
  pinocchio::computeJointJacobians(model_, data_, q);
  pinocchio::updateFramePlacements(model_, data_);
  if (python_) {
    python_force_.setZero(model_.nv);
    const VectorXd still = VectorXd::Zero(model_.nv);
    if (!python_->evaluate(t, q, still, python_jacobian_, python_phi_, python_time_term_, python_drift_,
                           python_force_)) {
      return false;
    }
  }
  int offset = 0, python_row = 0;
  for (const RowBlock& block : blocks_) {
    const int rows = block.rows();
    if (block.kind == RowKind::python) {  // the rows Python gave, in order
      phi_.segment(offset, rows) = python_phi_.segment(python_row, rows);
      jacobian_.middleRows(offset, rows) = python_jacobian_.middleRows(python_row, rows);
      time_term_.segment(offset, rows) = python_time_term_.segment(python_row, rows);
      python_row += rows;
    } else {
      block_residual(model_, data_, block, q, t, phi_.segment(offset, rows));
      block_jacobian(model_, data_, block, t, jacobian_.middleRows(offset, rows), time_term_.segment(offset, rows));
    }
    offset += rows;
  }
  const int enforced = static_cast<int>(holonomic_.size());
  enforced_jacobian_.resize(enforced, model_.nv);
  enforced_phi_.resize(enforced);
  for (int row = 0; row < enforced; ++row) {
    enforced_jacobian_.row(row) = jacobian_.row(holonomic_[row]);
    enforced_phi_(row) = phi_(holonomic_[row]);
  }
  finite_ = mass_.allFinite() && jacobian_.allFinite() && phi_.allFinite() && time_term_.allFinite();
  return finite_;
}

bool CoreProjection::position_step(const VectorXd& q, double t, VectorXd& step, double& worst) {
  if (!evaluate(q, t)) {
    worst = NOT_A_NUMBER;
    step.setConstant(model_.nv, NOT_A_NUMBER);
    return false;
  }
  worst = largest(enforced_phi_);
  if (!enforced_factored_) {
    enforced_factored_ = true;
    enforced_.factor(mass_, enforced_jacobian_, cutoff_);
  }
  return enforced_.apply(enforced_phi_, step, refining_);
}

bool CoreProjection::velocity_projection(const VectorXd& q, const VectorXd& v, double t, VectorXd& projected) {
  if (!evaluate(q, t)) {
    projected.setConstant(model_.nv, NOT_A_NUMBER);
    return false;
  }
  const LeastChange* rows = &every_;  // every row's factors: the holonomic rows' where they are every row
  if (every_row_holonomic_) {
    if (!enforced_factored_) enforced_.factor(mass_, enforced_jacobian_, cutoff_);
    enforced_factored_ = true;
    rows = &enforced_;
  } else if (!every_factored_) {
    every_.factor(mass_, jacobian_, cutoff_);
    every_factored_ = true;
  }
  VectorXd change;
  const bool finite = rows->apply(jacobian_ * v + time_term_, change, refining_);
  projected = v + change;
  return finite;
}

int CoreCorrection::correct(double t, VectorXd& q, VectorXd& v) {
  int iterations = 0;
  double worst = 0.0;
  const CorrectionOutcome outcome = pinstab::correct(*projections_, group_, post_, rule_, t, q, v, iterations, worst);
  return outcome == CorrectionOutcome::done ? iterations : -1;
}

}  // namespace pinstab
