// The banded path's evaluation (pinstab.paths.banded.BandedDynamics), compiled: the same terms from the same
// Pinocchio passes, the KKT matrix scattered into LAPACK's band storage and factored by banded_solve.
#include "banded_kernel.hpp"

#include "stabilization.hpp"

#include <algorithm>
#include <cmath>

#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea.hpp>

namespace pinstab {

namespace {

// y += A x for a CSR matrix A.
void multiply_add(const Csr& matrix, const double* x, double* y) {
  for (int row = 0; row < matrix.rows(); ++row) {
    double sum = 0.0;
    for (int entry = matrix.indptr(row); entry < matrix.indptr(row + 1); ++entry) {
      sum += matrix.data(entry) * x[matrix.indices(entry)];
    }
    y[row] += sum;
  }
}

}  // namespace

BandedKernel::BandedKernel(const pinocchio::Model& model, BandedPattern pattern, GramSpectrum::Pattern gram,
                           double kp, double kd, double pivot_tolerance, pinocchio::Data* data)
    : model_(model),
      own_data_(data == nullptr ? std::make_unique<pinocchio::Data>(light_data(model_)) : nullptr),
      data_(data == nullptr ? *own_data_ : *data),
      world_bias_(model_), world_(WorldBias::applies(model_)),
      pattern_(std::move(pattern)), spectrum_(std::move(gram)), kp_(kp), kd_(kd), pivot_tolerance_(pivot_tolerance) {
  const int points = static_cast<int>(pattern_.fixed_points.cols());
  const int size = static_cast<int>(pattern_.acceleration_slots.size() + pattern_.row_slots.size());
  points_ = pattern_.fixed_points;
  terms_.resize(3, points);
  rows_.resize(pattern_.row_slots.size());
  flat_points_.resize(3, points);
  raveled_.resize(3, points);
  lever_.resize(3 * pattern_.g_columns.size());
  g_values_.resize(pattern_.g_columns.size());
  values_.resize(pattern_.scatter.size());
  ab_.setZero(3 * pattern_.band + 1, size);
  rhs_.resize(size);
}

void BandedKernel::closure_rows(const Eigen::MatrixXd& per_point, VectorXd& rows) {
  // s_r . (T_b - T_a) for every closure row r, from per-point terms T (3, points) raveled by component (numpy's ravel)
  raveled_ = per_point;
  rows.setZero(pattern_.row_map.rows());
  multiply_add(pattern_.row_map, raveled_.data(), rows.data());
}

void BandedKernel::place_points() {
  // the carried closure points from their joints' placements (data_.oMi computed) [m]
  const BandedPattern& p = pattern_;
  for (int c = 0; c < p.carried.size(); ++c) {
    const pinocchio::SE3& placement = data_.oMi[p.joints(c)];
    points_.col(p.carried(c)) = placement.rotation() * p.local.row(c).transpose() + placement.translation();
  }
}

void BandedKernel::jacobian_values() {
  // the closure points, then G's entries: J[:, column] . c_e with c_e = [linear part; lever x s], the lever
  // linear in the points (data_.J and data_.oMi computed)
  const BandedPattern& p = pattern_;
  place_points();
  flat_points_ = points_;
  lever_.setZero();
  multiply_add(p.g_map, flat_points_.data(), lever_.data());
  const int entries = static_cast<int>(p.g_columns.size());
  const double* const lever = lever_.data();
  for (int e = 0; e < entries; ++e) {
    const double* const column = data_.J.col(p.g_columns(e)).data();
    const double x0 = column[0] * p.g_linear(0, e), x1 = column[1] * p.g_linear(1, e);
    const double x2 = column[2] * p.g_linear(2, e), x3 = column[3] * lever[e];
    const double x4 = column[4] * lever[entries + e], x5 = column[5] * lever[2 * entries + e];
    // the 6-term dot product summed as Eigen's SSE2 dot of the two columns sums it (pairs of lanes), to the bit;
    // from the factors directly: storing the lever part into a coefficient column first and reading it back as a
    // pair stalled the loads (store forwarding) for a third of this function's time
    g_values_(e) = ((x4 + x2) + x0) + ((x5 + x3) + x1);
  }
}

std::pair<double, double> BandedKernel::violation(const VectorXd& q, const VectorXd& v) {
  const BandedPattern& p = pattern_;
  pinocchio::forwardKinematics(model_, data_, q, v);
  place_points();
  terms_.setZero();  // the points' velocities (zero for world points), world axes [m/s]
  for (int c = 0; c < p.carried.size(); ++c) {
    const int joint = p.joints(c);
    const pinocchio::Motion velocity_0 = data_.oMi[joint].act(data_.v[joint]);
    const Eigen::Vector3d point = points_.col(p.carried(c));
    terms_.col(p.carried(c)) = velocity_0.linear() + velocity_0.angular().cross(point);
  }
  // the rows' differences of point positions (phi) and of point velocities (G v)
  VectorXd phi, rate;
  closure_rows(points_, phi);
  closure_rows(terms_, rate);
  return {phi.lpNorm<Eigen::Infinity>(), rate.lpNorm<Eigen::Infinity>()};
}

double BandedKernel::relative_singular_value(const VectorXd& q, int rank) {
  pinocchio::computeJointJacobians(model_, data_, q);
  jacobian_values();
  return spectrum_.relative(g_values_, rank);
}

bool BandedKernel::acceleration(int, double, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                                VectorXd& a) {
  const BandedPattern& p = pattern_;
  // crba (world convention) also gives the joint Jacobians and placements; the nonlinear effects' pass the
  // joints' spatial velocities and their accelerations at a = 0 with gravity's (a_gf): WorldBias from the
  // Jacobian where the joints allow it (world frame), else Pinocchio's nonLinearEffects (local frames)
  pinocchio::crba(model_, data_, q, pinocchio::Convention::WORLD);
  const VectorXd& bias =
      world_ ? world_bias_.compute(model_, data_, v) : pinocchio::nonLinearEffects(model_, data_, q, v);
  jacobian_values();
  const pinocchio::Motion gravity = model_.gravity;
  // a point's share of the corrector, Kp p + Kd v: the rows' -Kp phi - Kd G v once mapped (stabilization_law)
  const auto corrector = [this](const auto& position, const auto& velocity) {
    return -stabilization_law(kp_, kd_, velocity, position);
  };
  terms_ = corrector(points_, Eigen::MatrixXd::Zero(3, points_.cols()));  // points fixed in the world: no motion
  // a point's terms from the spatial velocity and the bias acceleration (without gravity's) of its body at the world
  // origin, world axes; taken by reference where WorldBias holds them (a copy read back as pairs of lanes stalled)
  const auto point_terms = [&](int point, const pinocchio::Motion& velocity_0, const pinocchio::Motion& acceleration_0) {
    const pinocchio::Motion bias_0 = acceleration_0 + gravity;
    const Eigen::Vector3d omega = velocity_0.angular();
    const Eigen::Vector3d position = points_.col(point);
    const Eigen::Vector3d velocity = velocity_0.linear() + omega.cross(position);
    terms_.col(point) =
        bias_0.linear() + bias_0.angular().cross(position) + omega.cross(velocity) + corrector(position, velocity);
  };
  for (int c = 0; c < p.carried.size(); ++c) {
    const int joint = p.joints(c);
    if (world_) {
      point_terms(p.carried(c), world_bias_.velocity(joint), world_bias_.acceleration(joint));
    } else {
      point_terms(p.carried(c), data_.oMi[joint].act(data_.v[joint]), data_.oMi[joint].act(data_.a_gf[joint]));
    }
  }
  // -gamma0 - Kp phi - Kd G v on the closure rows
  closure_rows(terms_, rows_);
  assemble_matrix();
  for (int i = 0; i < p.acceleration_slots.size(); ++i) rhs_(p.acceleration_slots(i)) = tau(i) - bias(i);
  for (int r = 0; r < p.row_slots.size(); ++r) rhs_(p.row_slots(r)) = rows_(r);
  const Outcome outcome = solve_assembled();
  singular_ = outcome == Outcome::singular;
  refinements_ += outcome == Outcome::refined ? 1 : 0;
  for (int i = 0; i < p.acceleration_slots.size(); ++i) a(i) = rhs_(p.acceleration_slots(i));
  return !singular_;
}

void BandedKernel::assemble_matrix() {
  // the KKT matrix's entries [M upper, M lower off-diagonal, G, G^T] (data_.M and g_values_ computed)
  const BandedPattern& p = pattern_;
  const int entries = static_cast<int>(p.g_columns.size());
  const int upper = static_cast<int>(p.m_rows.size());
  const int off = static_cast<int>(p.m_off.size());
  values_.segment(upper + off, entries) = g_values_;
  values_.segment(upper + off + entries, entries) = g_values_;
  for (int m = 0; m < upper; ++m) values_(m) = data_.M(p.m_rows(m), p.m_cols(m));
  for (int m = 0; m < off; ++m) values_(upper + m) = values_(p.m_off(m));
}

BandedKernel::Outcome BandedKernel::solve_assembled() {
  // the LU of the assembled KKT matrix applied to rhs_ (overwritten by the solution); a small pivot refined
  const BandedPattern& p = pattern_;
  scatter(ab_);
  right_ = rhs_;
  const int info = banded_solve(ab_, p.band, rhs_, pivots_);
  double smallest = INFINITY, largest = 0.0;
  for (int j = 0; j < ab_.cols(); ++j) {
    const double pivot = std::abs(ab_(2 * p.band, j));
    smallest = std::min(smallest, pivot);
    largest = std::max(largest, pivot);
  }
  pivot_ratio_ = smallest / largest;
  if (info == 0 && smallest > pivot_tolerance_ * largest) return Outcome::solved;
  if (info == 0 && smallest > REFINABLE * largest && refine()) return Outcome::refined;
  return Outcome::singular;
}

std::pair<VectorXd, VectorXd> BandedKernel::values(const VectorXd& q) {
  pinocchio::computeJointJacobians(model_, data_, q);
  jacobian_values();
  VectorXd phi;
  closure_rows(points_, phi);  // s . (p_b - p_a) = -phi
  return {-phi, g_values_};
}

bool BandedKernel::project(const VectorXd& q, const VectorXd& rows, VectorXd& x) {
  const BandedPattern& p = pattern_;
  pinocchio::crba(model_, data_, q, pinocchio::Convention::WORLD);
  jacobian_values();
  assemble_matrix();
  for (int i = 0; i < p.acceleration_slots.size(); ++i) rhs_(p.acceleration_slots(i)) = 0.0;
  for (int r = 0; r < p.row_slots.size(); ++r) rhs_(p.row_slots(r)) = rows(r);
  if (solve_assembled() == Outcome::singular) return false;
  x.resize(p.acceleration_slots.size());
  for (int i = 0; i < x.size(); ++i) x(i) = rhs_(p.acceleration_slots(i));
  return x.allFinite();
}

void BandedKernel::scatter(Eigen::MatrixXd& band) const {
  band.setZero();
  double* const storage = band.data();
  for (int i = 0; i < values_.size(); ++i) storage[pattern_.scatter(i)] = values_(i);
}

bool BandedKernel::refine() {
  // a small pivot: rows near dependence, the LU's solution as inaccurate as the KKT matrix is ill-conditioned;
  // iterative refinement with residuals in extended precision brings it to rounding while the factors still
  // contract the error (condition number times 1e-16 below 1), else says it does not converge
  const BandedPattern& p = pattern_;
  kkt_.resizeLike(ab_);
  scatter(kkt_);
  correction_.resizeLike(rhs_);
  for (int iteration = 0; iteration < MAX_REFINEMENTS; ++iteration) {
    banded_residual(kkt_, p.band, rhs_, right_, correction_);
    banded_substitute(ab_, p.band, pivots_, correction_);
    if (!correction_.allFinite()) return false;
    rhs_ += correction_;
    double change = 0.0, size = 0.0;  // accelerations and multipliers each relative to their own size
    for (const VectorXi* slots : {&p.acceleration_slots, &p.row_slots}) {
      double part_change = 0.0, part_size = 0.0;
      for (int i = 0; i < slots->size(); ++i) {
        part_change = std::max(part_change, std::abs(correction_((*slots)(i))));
        part_size = std::max(part_size, std::abs(rhs_((*slots)(i))));
      }
      change = std::max(change, part_change / std::max(part_size, 1e-300));
      size = std::max(size, part_size);
    }
    if (change <= REFINED) return std::isfinite(size);
  }
  return false;
}

VectorXd BandedKernel::multipliers() const {
  VectorXd result(pattern_.row_slots.size());
  for (int r = 0; r < result.size(); ++r) result(r) = -rhs_(pattern_.row_slots(r));
  return result;
}

}  // namespace pinstab
