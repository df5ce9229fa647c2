#include "core_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>

namespace pinstab {

void add_joint_springs(const std::vector<JointSpringSpec>& springs, const VectorXd& q, const VectorXd& v,
                       Eigen::Ref<VectorXd> force) {
  for (const JointSpringSpec& spring : springs) {
    if (spring.q_index < 0) {
      for (int k = 0; k < spring.dofs.size(); ++k) force(spring.dofs(k)) += -spring.damping * v(spring.dofs(k));
      continue;
    }
    const int dof = spring.dofs(0);
    force(dof) += -(spring.stiffness * (q(spring.q_index) - spring.reference) + spring.damping * v(dof));
  }
}

Eigen::Vector3d GravityTilt::gravity(double t) const {
  return Eigen::AngleAxisd(-start - rate * t, axis).toRotationMatrix() * gravity0;
}

CoreKernel::CoreKernel(const pinocchio::Model& model, std::vector<RowBlock> blocks, CoreForces forces, double kp,
                       double kd, CoreSolve solve, std::optional<GravityTilt> tilt,
                       std::shared_ptr<PythonPart> python)
    : model_(model),
      data_(light_data(model_)),
      blocks_(std::move(blocks)),
      forces_(std::move(forces)),
      tilt_(std::move(tilt)),
      python_(std::move(python)),
      kp_(kp),
      kd_(kd),
      settings_(solve),
      rows_(0) {
  for (const RowBlock& block : blocks_) {
    offsets_.push_back(rows_);
    rows_ += block.rows();
    if (block.kind == RowKind::python) python_rows_ += block.rows();
  }
  python_jacobian_.setZero(python_rows_, model_.nv);
  python_phi_.setZero(python_rows_);
  python_time_term_.setZero(python_rows_);
  python_drift_.setZero(python_rows_);
  velocity_gain_.resize(rows_);
  for (size_t k = 0; k < blocks_.size(); ++k) {  // Baumgarte's Kd on holonomic rows, Kd / 2 on nonholonomic ones
    velocity_gain_.segment(offsets_[k], blocks_[k].rows()).setConstant(blocks_[k].holonomic ? kd_ : 0.5 * kd_);
  }
  jacobian_.setZero(rows_, model_.nv);
  phi_.setZero(rows_);
  time_term_.setZero(rows_);
  drift_.setZero(rows_);
  multipliers_.setZero(rows_);
}

bool CoreKernel::acceleration(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) {
  if (tilt_) model_.gravity.linear() = tilt_->gravity(t);
  // one pass: placements, Jacobians, velocities and accelerations at zero joint acceleration, M, h
  pinocchio::computeAllTerms(model_, data_, q, v);
  pinocchio::updateFramePlacements(model_, data_);
  data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose().triangularView<Eigen::StrictlyLower>();
  force_ = tau;
  if (python_ && !python_->evaluate(t, q, v, python_jacobian_, python_phi_, python_time_term_, python_drift_, force_)) {
    ++status_counts_["python part not usable"];
    return false;
  }
  int python_row = 0;
  for (size_t k = 0; k < blocks_.size(); ++k) {
    const RowBlock& block = blocks_[k];
    const int offset = offsets_[k], rows = block.rows();
    if (block.kind == RowKind::python) {  // the rows Python gave, in order
      phi_.segment(offset, rows) = python_phi_.segment(python_row, rows);
      jacobian_.middleRows(offset, rows) = python_jacobian_.middleRows(python_row, rows);
      time_term_.segment(offset, rows) = python_time_term_.segment(python_row, rows);
      drift_.segment(offset, rows) = python_drift_.segment(python_row, rows);
      python_row += rows;
      continue;
    }
    block_residual(model_, data_, block, q, t, phi_.segment(offset, rows));
    block_jacobian(model_, data_, block, t, jacobian_.middleRows(offset, rows), time_term_.segment(offset, rows));
    block_drift(model_, data_, block, t, drift_.segment(offset, rows));
  }
  add_joint_springs(forces_.springs, q, v, force_);
  for (const WrenchSpec& wrench : forces_.wrenches) add_wrench(model_, data_, wrench, force_);
  for (const HoldSpec& hold : forces_.holds) {
    if (!add_hold_torques(model_, data_, hold, jacobian_, q, v, force_)) {
      ++status_counts_["hold outside its cones"];
      return false;
    }
  }
  force_ -= data_.nle;
  const VectorXd rhs = -drift_ - (velocity_gain_.array() * (jacobian_ * v + time_term_).array()).matrix() - kp_ * phi_;
  if (!solve(rhs)) return false;
  if (!inside_limits() || (python_ && !python_->holds(t, multipliers_))) {
    ++status_counts_["outside a contact's limits"];
    return false;
  }
  a = acceleration_;
  return true;
}

// pinstab.contact.models.ContactLimits.check on every fingertip block's multipliers (components of the wrench in C)
bool CoreKernel::inside_limits() const {
  for (size_t k = 0; k < blocks_.size(); ++k) {
    const RowBlock& block = blocks_[k];
    if (block.kind != RowKind::fingertip) continue;
    Eigen::Matrix<double, 6, 1> wrench = Eigen::Matrix<double, 6, 1>::Zero();
    for (int c = 0; c < block.components.size(); ++c) wrench(block.components(c)) = multipliers_(offsets_[k] + c);
    if (!contact_holds(block.contact_model, block.mu, block.torsion, wrench, settings_.margin_slack)) return false;
  }
  return true;
}

bool CoreKernel::solve(const VectorXd& rhs) {
  mass_.compute(data_.M);
  if (mass_.info() != Eigen::Success) return false;
  free_ = mass_.solve(force_);
  acceleration_ = free_;
  if (rows_ == 0) {
    ++status_counts_["cholesky"];
    return acceleration_.allFinite();
  }
  spread_ = mass_.solve(jacobian_.transpose());
  delassus_.noalias() = jacobian_ * spread_;
  const VectorXd demand = rhs - jacobian_ * free_;
  const double largest = delassus_.diagonal().maxCoeff();
  inner_.compute(delassus_);
  if (inner_.info() == Eigen::Success &&
      independent_by_margin(inner_.matrixLLT().diagonal(), largest, settings_.direct_pivot)) {  // the direct solve
    multipliers_ = inner_.solve(demand);
    acceleration_.noalias() += spread_ * multipliers_;
    ++status_counts_["cholesky"];
    if (!acceleration_.allFinite()) return false;
    worst_residual_ =
        std::max(worst_residual_, primal_residual(jacobian_, acceleration_, rhs, force_, data_.M.diagonal()));
    return true;
  }
  // redundant or nearly dependent rows: the pseudo-inverse of D, eigenvalues below cutoff times the largest left out
  spectrum_.compute(delassus_);
  if (spectrum_.info() != Eigen::Success) return false;
  const VectorXd& values = spectrum_.eigenvalues();  // ascending
  const double floor = settings_.cutoff * values(values.size() - 1);
  const VectorXd projected = spectrum_.eigenvectors().transpose() * demand;
  VectorXd scaled = VectorXd::Zero(values.size());
  for (int k = 0; k < values.size(); ++k) {
    if (values(k) > floor) scaled(k) = projected(k) / values(k);
  }
  multipliers_ = spectrum_.eigenvectors() * scaled;
  acceleration_.noalias() += spread_ * multipliers_;
  const double residual = primal_residual(jacobian_, acceleration_, rhs, force_, data_.M.diagonal());
  if (!(residual <= settings_.accepted) || !acceleration_.allFinite()) {
    ++status_counts_["pseudo-inverse, not accepted"];
    return false;
  }
  ++status_counts_["pseudo-inverse"];
  worst_residual_ = std::max(worst_residual_, residual);
  return true;
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
