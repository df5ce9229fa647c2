#include "grasp_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/SVD>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>

#include "contact_terms.hpp"

namespace pinstab {

GraspKernel::GraspKernel(const pinocchio::Model& model, std::vector<FingertipSpec> contacts,
                         std::vector<HoldSpec> holds, std::vector<WrenchSpec> wrenches, double kp, double kd,
                         double direct_pivot, double margin_slack)
    : model_(model),
      data_(light_data(model_)),
      contacts_(std::move(contacts)),
      holds_(std::move(holds)),
      wrenches_(std::move(wrenches)),
      kp_(kp),
      kd_(kd),
      direct_pivot_(direct_pivot),
      margin_slack_(margin_slack),
      rows_(0),
      worst_residual_(0.0),
      frame_jacobian_(Eigen::MatrixXd::Zero(6, model_.nv)) {
  for (const FingertipSpec& contact : contacts_) rows_ += static_cast<int>(contact.components.size());
  jacobian_.resize(rows_, model_.nv);
  phi_.resize(rows_);
  drift_.resize(rows_);
}

bool GraspKernel::acceleration(double, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) {
  // one pass: placements, Jacobians, velocities and accelerations at zero joint acceleration, M, h, g
  pinocchio::computeAllTerms(model_, data_, q, v);
  pinocchio::updateFramePlacements(model_, data_);
  data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose().triangularView<Eigen::StrictlyLower>();
  int row = 0;
  for (const FingertipSpec& contact : contacts_) {
    const Eigen::Vector3d residual = contact_point_residual(model_, data_, contact.object_frame, contact.finger_frame);
    const Eigen::MatrixXd rows = contact_point_jacobian(model_, data_, contact.object_frame, contact.finger_frame);
    const Eigen::Vector3d drift = contact_point_drift(model_, data_, contact.object_frame, contact.finger_frame);
    for (int component : contact.components) {
      phi_(row) = residual(component);
      jacobian_.row(row) = rows.row(component);
      drift_(row) = drift(component);
      ++row;
    }
  }
  force_ = tau;
  for (const WrenchSpec& wrench : wrenches_) {
    frame_jacobian_.setZero();
    pinocchio::getFrameJacobian(model_, data_, wrench.frame, pinocchio::LOCAL_WORLD_ALIGNED, frame_jacobian_);
    force_.noalias() += frame_jacobian_.transpose() * wrench.wrench;
  }
  for (const HoldSpec& hold : holds_) {
    if (!hold_torques(hold, q, v, force_)) return false;
  }
  force_ -= data_.nle;
  // the direct solve of pinstab.solvers.proxsuite_.direct_solve
  mass_.compute(data_.M);
  if (mass_.info() != Eigen::Success) return false;
  free_ = mass_.solve(force_);
  spread_ = mass_.solve(jacobian_.transpose());
  delassus_.noalias() = jacobian_ * spread_;
  inner_.compute(delassus_);
  if (inner_.info() != Eigen::Success) return false;
  const double smallest = inner_.matrixLLT().diagonal().minCoeff();
  if (rows_ > 0 && !(smallest * smallest >= direct_pivot_ * delassus_.diagonal().maxCoeff())) return false;
  const VectorXd velocity_residual = jacobian_ * v;
  const VectorXd rhs = -drift_ + (-kd_ * velocity_residual - kp_ * phi_);
  multipliers_ = inner_.solve(rhs - jacobian_ * free_);
  a = free_;
  a.noalias() += spread_ * multipliers_;
  if (!a.allFinite() || !inside_cones()) return false;
  worst_residual_ = std::max(worst_residual_, primal_residual(jacobian_, a, rhs, force_, data_.M));
  return true;
}

bool GraspKernel::hold_torques(const HoldSpec& hold, const VectorXd& q, const VectorXd& v, VectorXd& force) {
  const int count = static_cast<int>(hold.rows.size());
  Eigen::MatrixXd carrier(hold.object_columns.size(), count);  // A_object^T
  VectorXd load(hold.object_columns.size());
  for (int i = 0; i < hold.object_columns.size(); ++i) {
    for (int k = 0; k < count; ++k) carrier(i, k) = jacobian_(hold.rows(k), hold.object_columns(i));
    load(i) = data_.g(hold.object_columns(i));
  }
  VectorXd forces;
  if (!closest_solution(hold, carrier, load, forces) || !holds(hold, forces)) return false;
  VectorXd deviation(model_.nv);
  pinocchio::difference(model_, hold.q_start, q, deviation);
  for (int i = 0; i < hold.hand_columns.size(); ++i) {
    const int column = hold.hand_columns(i);
    double pushed = 0.0;
    for (int k = 0; k < count; ++k) pushed += jacobian_(hold.rows(k), column) * forces(k);
    force(column) += data_.g(column) - pushed - hold.stiffness * deviation(column) - hold.damping * v(column);
  }
  return true;
}

// pinstab.grasp.linalg.closest_solution with the squeeze as target: target + A^+ (rhs - A target), through the
// Cholesky factor of A A^T where its condition allows, else the SVD with small singular values dropped
bool GraspKernel::closest_solution(const HoldSpec& hold, const Eigen::MatrixXd& matrix, const VectorXd& rhs,
                                   VectorXd& x) {
  const VectorXd& target = hold.pressing;
  const VectorXd residual = rhs - matrix * target;
  if (matrix.rows() <= matrix.cols()) {
    const Eigen::LLT<Eigen::MatrixXd> gram(matrix * matrix.transpose());
    const double condition = hold.condition;
    if (gram.info() == Eigen::Success && gram.rcond() * condition * condition >= 1.0) {
      x = target + matrix.transpose() * gram.solve(residual);
      return x.allFinite();
    }
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(matrix, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const VectorXd& singular = svd.singularValues();
  const double floor = hold.rank * std::max(singular.size() ? singular(0) : 0.0, 1.0);
  x = target;
  for (int k = 0; k < singular.size() && singular(k) > floor; ++k) {
    x += svd.matrixV().col(k) * (svd.matrixU().col(k).dot(residual) / singular(k));
  }
  return x.allFinite();
}

// pinstab.grasp.holding.ConeTest.holds and GraspHold._holds: every contact inside its cone, every normal force within
// the cap, beyond a rounding slack relative to the largest force
bool GraspKernel::holds(const HoldSpec& hold, const VectorXd& forces) {
  const double slack = -hold.feasibility * (1.0 + forces.cwiseAbs().maxCoeff());
  for (const ConeSpec& cone : hold.cones) {
    const double normal = forces(cone.normal);
    if (normal < slack) return false;
    if (cone.tangent1 >= 0 && cone.mu * normal - std::hypot(forces(cone.tangent1), forces(cone.tangent2)) < slack) {
      return false;
    }
    if (std::isfinite(hold.cap) && normal > hold.cap * (1.0 + 1e-9)) return false;
  }
  return true;
}

// pinstab.contact.models.ContactLimits.check on every contact's multipliers (in C: x, y tangents, z normal)
bool GraspKernel::inside_cones() const {
  int row = 0;
  for (const FingertipSpec& contact : contacts_) {
    Eigen::Vector3d wrench = Eigen::Vector3d::Zero();
    for (int component : contact.components) wrench(component) = multipliers_(row++);
    const double slack = -margin_slack_ * (1.0 + wrench.cwiseAbs().maxCoeff());
    if (!(wrench(2) >= slack)) return false;
    if (contact.components.size() == 3 && !(contact.mu * wrench(2) - std::hypot(wrench(0), wrench(1)) >= slack)) {
      return false;
    }
  }
  return true;
}

}  // namespace pinstab
