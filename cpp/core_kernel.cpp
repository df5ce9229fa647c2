#include "core_kernel.hpp"

#include "stabilization.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>

namespace pinstab {

Eigen::ArrayXd baumgarte_velocity_gains(double kd, const Mask& holonomic) {
  return holonomic.select(Eigen::ArrayXd::Constant(holonomic.size(), kd), 0.5 * kd);
}

VectorXd stabilization_term(double stiffness, const Eigen::ArrayXd& velocity_gains, const VectorXd& phi,
                            const VectorXd& rate) {
  return stabilization_law(stiffness, velocity_gains, rate.array(), phi.array()).matrix();
}

Eigen::Vector3d GravityTilt::gravity(double t) const {
  const double turning = start + rate * t;
  const double angle = std::isinf(stop) ? turning : (rate > 0.0 ? std::min(turning, stop) : std::max(turning, stop));
  return Eigen::AngleAxisd(-angle, axis).toRotationMatrix() * gravity0;
}

CoreKernel::CoreKernel(const pinocchio::Model& model, std::vector<RowBlock> blocks, CoreForces forces, CoreTerm term,
                       CoreSolve solve, std::optional<GravityTilt> tilt,
                       std::shared_ptr<PythonPart> python)
    : model_(model),
      data_(light_data(model_)),
      blocks_(std::move(blocks)),
      forces_(std::move(forces)),
      tilt_(std::move(tilt)),
      python_(std::move(python)),
      term_(std::move(term)),
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
  if (term_.velocity_gains.size() != rows_) {
    throw std::invalid_argument("CoreKernel: the term's velocity gains need one entry per row");
  }
  if (term_.inertial) {
    if (python_rows_ > 0) throw std::invalid_argument("CoreKernel: the inertial term needs every row compiled");
    inertial_.emplace(model_, *term_.inertial);
  }
  jacobian_.setZero(rows_, model_.nv);
  phi_.setZero(rows_);
  time_term_.setZero(rows_);
  drift_.setZero(rows_);
  multipliers_.setZero(rows_);
}

bool CoreKernel::acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                              VectorXd& a) {
  if (tilt_) model_.gravity.linear() = tilt_->gravity(t);
  // one pass: placements, Jacobians, velocities and accelerations at zero joint acceleration, M, h
  pinocchio::computeAllTerms(model_, data_, q, v);
  pinocchio::updateFramePlacements(model_, data_);
  data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose().triangularView<Eigen::StrictlyLower>();
  force_ = tau;
  const bool holds_term = term_.held && stage > 0;
  if (term_.held && !holds_term) held_.reset();  // a new step: its term is this evaluation's
  if (holds_term && !held_) {
    ++status_counts_["no held term"];
    return false;
  }
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
  if (!holds_term) {
    const VectorXd rate = jacobian_ * v + time_term_;
    term_value_ = inertial_ ? inertial_->term(model_, blocks_, offsets_, t, q, v, data_.M, jacobian_, phi_, rate)
                            : stabilization_term(term_.stiffness, term_.velocity_gains, phi_, rate);
    if (term_.held) held_ = term_value_;
  }
  if (!add_force_elements(model_, data_, forces_, t, q, v, force_)) {  // a spring-damper's points coincide: it says so
    ++status_counts_["spring-damper without a direction"];
    return false;
  }
  for (const HoldSpec& hold : forces_.holds) {
    if (!add_hold_torques(model_, data_, hold, jacobian_, q, v, force_)) {
      ++status_counts_["hold outside its cones"];
      return false;
    }
  }
  force_ -= data_.nle;
  const VectorXd rhs = -drift_ + (holds_term ? *held_ : term_value_);
  if (contacts_) {  // the contacts in their modes, the rows held
    if (!contacts_->solve(model_, data_, v, data_.M, force_, jacobian_, rhs)) {
      ++status_counts_["contact modes not solved"];
      return false;
    }
    ++status_counts_["contact modes"];
    multipliers_ = contacts_->reactions();
    a = contacts_->acceleration();
    return true;
  }
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
  switch (kkt_.solve(model_, data_, force_, jacobian_, rhs, settings_, true)) {
    case KktOutcome::direct:
      ++status_counts_["cholesky"];
      break;
    case KktOutcome::pseudo_inverse:
      ++status_counts_["pseudo-inverse"];
      break;
    case KktOutcome::not_accepted:
      ++status_counts_["pseudo-inverse, not accepted"];
      return false;
    default:
      return false;
  }
  multipliers_ = kkt_.multipliers();
  acceleration_ = kkt_.acceleration();
  worst_residual_ = std::max(worst_residual_, kkt_.residual());
  return true;
}

}  // namespace pinstab
