#include "contact_modes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/QR>

namespace pinstab {

using Eigen::MatrixXd;

Eigen::Vector2d unit_slip(const Eigen::Vector2d& slip, const Eigen::Vector2d& fallback,
                          const Eigen::Vector2d& reference, bool continued, double floor) {
  if (continued && slip.dot(reference) <= 0.0) return reference;
  const double speed = std::hypot(slip(0), slip(1));
  return speed > floor ? Eigen::Vector2d(slip / speed) : fallback;
}

ContactModes::ContactModes(std::vector<PlaneContact> contacts, VectorXd mus, ContactSettings settings)
    : contacts_(std::move(contacts)), mus_(std::move(mus)), settings_(settings) {
  if (mus_.size() != size()) throw std::invalid_argument("ContactModes: one mu a contact");
  const int k = size();
  modes_.assign(k, ContactMode::separated);
  directions_ = MatrixXd::Zero(k, 2);
  directions_.col(0).setOnes();
  references_ = directions_;
  continued_ = Mask::Constant(k, false);
}

void ContactModes::set_modes(const std::vector<ContactMode>& modes, const MatrixXd& directions,
                             const MatrixXd& references, const Mask& continued) {
  const int k = size();
  if (static_cast<int>(modes.size()) != k || directions.rows() != k || directions.cols() != 2 ||
      references.rows() != k || references.cols() != 2 || continued.size() != k) {
    throw std::invalid_argument("ContactModes.set_modes: one mode, direction (t1, t2), reference and flag a contact");
  }
  modes_ = modes;
  directions_ = directions;
  references_ = references;
  continued_ = continued;
}

MatrixXd ContactModes::forces() const {
  MatrixXd forces(size(), 3);
  for (int i = 0; i < size(); ++i) forces.row(i) = forces_.segment<3>(3 * i).transpose();
  return forces;
}

// The contacts' rows at the state (cpp/plane_contacts.hpp); false: a gap not finite.
bool ContactModes::kinematics(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& v) {
  rows_ = plane_contact_rows(model, data, contacts_, v);
  jacobian_ = rows_.jacobian;
  return rows_.gaps.allFinite();
}

// ModeDynamics._held with the targets zero but on the first column: B (unheld + held lambda) = targets through B^T's
// complete orthogonal decomposition B^T P = Q [T 0; 0 0] Z (rank at held_rank): a = B^+ target + N z on B's range and
// null space N (Q's last columns), N^T M N z = N^T (columns - M B^+ target); the reactions lambda = (B^T)^+ (M a -
// columns), the least-norm ones.
bool ContactModes::held(const MatrixXd& mass, const MatrixXd& rows, const MatrixXd& columns, const VectorXd& target,
                        MatrixXd& response, MatrixXd& reactions) const {
  const Eigen::Index nv = mass.rows();
  if (rows.rows() == 0) {
    Eigen::LLT<MatrixXd> factor(mass);
    if (factor.info() != Eigen::Success) return false;
    response = factor.solve(columns);
    reactions.resize(0, columns.cols());
    return true;
  }
  Eigen::CompleteOrthogonalDecomposition<MatrixXd> decomposition;
  decomposition.setThreshold(settings_.held_rank);
  decomposition.compute(rows.transpose());
  const Eigen::Index loose = nv - decomposition.rank();
  MatrixXd ranged = MatrixXd::Zero(nv, columns.cols());
  ranged.col(0) = decomposition.transpose().solve(target);  // B^+ target, the least-norm least squares
  MatrixXd null = MatrixXd::Zero(nv, loose);
  null.bottomRows(loose).setIdentity();
  null.applyOnTheLeft(decomposition.householderQ());
  Eigen::LLT<MatrixXd> factor(null.transpose() * mass * null);
  if (factor.info() != Eigen::Success) return false;
  response = ranged + null * factor.solve(null.transpose() * (columns - mass * ranged));
  reactions = decomposition.solve(mass * response - columns);
  return true;
}

// ModeDynamics' _forces: the solve where the modes' system has full rank (its condition below 1 / rank_tolerance,
// decided once per modes), else the least-norm least squares (rank at rank_tolerance) refined once on its residual.
bool ContactModes::forces_of(const MatrixXd& system, const VectorXd& rhs) {
  std::vector<int> key(modes_.size());
  for (size_t i = 0; i < modes_.size(); ++i) key[i] = static_cast<int>(modes_[i]);
  auto found = redundant_.find(key);
  if (found == redundant_.end()) {
    const VectorXd singular = Eigen::JacobiSVD<MatrixXd>(system).singularValues();
    const double condition = singular(0) / singular(singular.size() - 1);
    found = redundant_.emplace(key, !(condition < 1.0 / settings_.rank_tolerance)).first;
  }
  bool solved = false;
  if (!found->second) {
    forces_ = system.partialPivLu().solve(rhs);
    solved = forces_.allFinite();
  }
  if (!solved) {
    Eigen::CompleteOrthogonalDecomposition<MatrixXd> decomposition;
    decomposition.setThreshold(settings_.rank_tolerance);
    decomposition.compute(system);
    forces_ = decomposition.solve(rhs);
    forces_ += decomposition.solve(rhs - system * forces_);
  }
  if (!forces_.allFinite()) return false;
  const double scale = std::max({rhs.norm(), system.norm() * forces_.norm(), std::numeric_limits<double>::min()});
  residual_ = (system * forces_ - rhs).norm() / scale;
  return true;
}

bool ContactModes::solve(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& v, const MatrixXd& mass,
                         const VectorXd& force, const MatrixXd& rows, const VectorXd& target) {
  if (!kinematics(model, data, v)) return false;
  const int k = size(), linear = 3 * k, nv = model.nv;
  MatrixXd columns(nv, 1 + linear), response, reactions;
  columns.col(0) = force;
  columns.rightCols(linear) = jacobian_.transpose();
  if (!held(mass, rows, columns, target, response, reactions)) return false;
  free_ = response.col(0);
  mobility_ = response.rightCols(linear);
  const MatrixXd delassus = jacobian_ * mobility_;
  const VectorXd reach = jacobian_ * free_ + rows_.drift;  // the contact accelerations without forces
  MatrixXd system = MatrixXd::Zero(linear, linear);
  VectorXd rhs = VectorXd::Zero(linear);
  for (int i = 0; i < k; ++i) {
    const int row = 3 * i;
    switch (modes_[i]) {
      case ContactMode::separated:
        system.block<3, 3>(row, row).setIdentity();
        break;
      case ContactMode::sticking:
        system.middleRows<3>(row) = delassus.middleRows<3>(row);
        rhs.segment<3>(row) = -reach.segment<3>(row);
        break;
      case ContactMode::sliding: {  // the normal row, then f_t + mu f_n d = 0
        system.row(row) = delassus.row(row);
        rhs(row) = -reach(row);
        const Eigen::Vector2d slip = rows_.velocities.row(i).tail<2>().transpose();
        if (mus_(i) > 0.0 && std::hypot(slip(0), slip(1)) < settings_.grazing_speed) return false;
        const Eigen::Vector2d direction =
            unit_slip(slip, directions_.row(i).transpose(), references_.row(i).transpose(), continued_(i),
                      settings_.slip_floor);
        system.block<2, 2>(row + 1, row + 1).setIdentity();
        system.block<2, 1>(row + 1, row) = mus_(i) * direction;
        break;
      }
    }
  }
  forces_ = VectorXd::Zero(linear);
  if (k > 0 && !forces_of(system, rhs)) return false;
  acceleration_ = free_ + mobility_ * forces_;
  reactions_ = rows.rows() ? VectorXd(reactions.col(0) + reactions.rightCols(linear) * forces_) : VectorXd(0);
  return true;
}

}  // namespace pinstab
