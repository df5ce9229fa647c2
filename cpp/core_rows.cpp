#include "core_rows.hpp"

#include "contact_terms.hpp"

#include <cmath>
#include <stdexcept>

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/spatial/explog.hpp>
#include <pinocchio/spatial/skew.hpp>

namespace pinstab {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Matrix6x = Eigen::Matrix<double, 6, Eigen::Dynamic>;
constexpr auto LWA = pinocchio::LOCAL_WORLD_ALIGNED;

// The two sides of a frame block: placements, and (on demand) Jacobians, velocities and drift accelerations in
// LOCAL_WORLD_ALIGNED; side b is the world placement `world` when frame_b < 0 (zero Jacobian; fixed, or a
// frame_target's moving one with its velocity and acceleration, see at()).
struct Sides {
  const pinocchio::Model& model;
  pinocchio::Data& data;
  const RowBlock& block;
  pinocchio::SE3 world = block.world_b;
  pinocchio::Motion world_velocity = pinocchio::Motion::Zero(), world_acceleration = pinocchio::Motion::Zero();

  // The sides at time t [s]: a frame_target's side b at (p(t), exp(turn(t) axis) R_0), moving at (p', turn' axis)
  // [m/s, rad/s] with acceleration (p'', turn'' axis) [m/s^2, rad/s^2].
  static Sides at(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t) {
    Sides sides{model, data, block};
    if (block.kind != RowKind::frame_target) return sides;
    double angle, rate, curvature;
    block.target.evaluate(t, angle, rate, curvature);
    sides.world.rotation(pinocchio::exp3(Vector3d(angle * block.axis)) * block.world_b.rotation());
    sides.world_velocity.angular(rate * block.axis);
    sides.world_acceleration.angular(curvature * block.axis);
    if (!block.path.components.empty()) {
      VectorXd position, velocity, acceleration;
      block.path.evaluate(t, position, velocity, acceleration);
      sides.world.translation(position);
      sides.world_velocity.linear(velocity);
      sides.world_acceleration.linear(acceleration);
    }
    return sides;
  }
  const pinocchio::SE3& a() const { return data.oMf[block.frame_a]; }
  const pinocchio::SE3& b() const { return block.frame_b < 0 ? world : data.oMf[block.frame_b]; }
  bool moving_b() const { return block.frame_b >= 0; }
  Matrix6x jacobian(int frame) const {
    Matrix6x jacobian = Matrix6x::Zero(6, model.nv);
    pinocchio::getFrameJacobian(model, data, frame, LWA, jacobian);
    return jacobian;
  }
  pinocchio::Motion velocity(int frame) const { return pinocchio::getFrameVelocity(model, data, frame, LWA); }
  pinocchio::Motion drift(int frame) const {
    return pinocchio::getFrameClassicalAcceleration(model, data, frame, LWA);
  }
  pinocchio::Motion velocity_b() const { return moving_b() ? velocity(block.frame_b) : world_velocity; }
  pinocchio::Motion drift_b() const { return moving_b() ? drift(block.frame_b) : world_acceleration; }
};

Matrix3d jlog(const Matrix3d& rotation) {
  Matrix3d jacobian;
  pinocchio::Jlog3(rotation, jacobian);
  return jacobian;
}

// The weld's six rows (points in world axes, then log3(R_b^T R_a)), from which the other frame kinds select.
Eigen::Matrix<double, 6, 1> weld_residual(const Sides& sides) {
  Eigen::Matrix<double, 6, 1> weld;
  weld.head<3>() = sides.a().translation() - sides.b().translation();
  weld.tail<3>() = pinocchio::log3(Matrix3d(sides.b().rotation().transpose() * sides.a().rotation()));
  return weld;
}

Matrix6x weld_jacobian(const Sides& sides) {
  Matrix6x relative = sides.jacobian(sides.block.frame_a);
  if (sides.moving_b()) relative -= sides.jacobian(sides.block.frame_b);
  const Matrix3d& rotation_a = sides.a().rotation();
  const Matrix3d rel = sides.b().rotation().transpose() * rotation_a;
  Matrix6x weld(6, sides.model.nv);
  weld.topRows<3>() = relative.topRows<3>();
  weld.bottomRows<3>() = jlog(rel) * rotation_a.transpose() * relative.bottomRows<3>();
  return weld;
}

// The weld's time term g_t: side b's world motion through the rows, -(v_b, Jlog3(R_b^T R_a) R_a^T w_b) (zero but for
// a frame_target's moving world side).
Eigen::Matrix<double, 6, 1> weld_time_term(const Sides& sides) {
  const Matrix3d& rotation_a = sides.a().rotation();
  Eigen::Matrix<double, 6, 1> weld;
  weld.head<3>() = -sides.world_velocity.linear();
  weld.tail<3>() = -(jlog(sides.b().rotation().transpose() * rotation_a) *
                     (rotation_a.transpose() * sides.world_velocity.angular()));
  return weld;
}

// The weld's six rows of G v + g_t: the points' relative velocity, then Jlog3(R_b^T R_a) R_a^T (w_a - w_b).
Eigen::Matrix<double, 6, 1> weld_rate(const Sides& sides) {
  const pinocchio::Motion velocity_a = sides.velocity(sides.block.frame_a), velocity_b = sides.velocity_b();
  const Vector3d angular = velocity_a.angular() - velocity_b.angular();
  const Matrix3d& rotation_a = sides.a().rotation();
  Eigen::Matrix<double, 6, 1> weld;
  weld.head<3>() = velocity_a.linear() - velocity_b.linear();
  weld.tail<3>() = jlog(sides.b().rotation().transpose() * rotation_a) * (rotation_a.transpose() * angular);
  return weld;
}

Eigen::Matrix<double, 6, 1> weld_drift(const Sides& sides) {
  const pinocchio::Motion drift_a = sides.drift(sides.block.frame_a), drift_b = sides.drift_b();
  Eigen::Matrix<double, 6, 1> weld;
  weld.head<3>() = drift_a.linear() - drift_b.linear();
  weld.tail<3>() = rotation_drift(sides.a().rotation(), sides.b().rotation(),
                                  sides.velocity(sides.block.frame_a).angular(), sides.velocity_b().angular(),
                                  drift_a.angular() - drift_b.angular());
  return weld;
}

// The components of a weld's six values (a fingertip's or a frame_target's rows).
void select(const RowBlock& block, const Eigen::Matrix<double, 6, 1>& full, Eigen::Ref<VectorXd> rows) {
  for (int k = 0; k < block.components.size(); ++k) rows(k) = full(block.components(k));
}

// A fingertip block with rotation rows (soft-finger, rigid): the last component is a moment's.
bool rotates(const RowBlock& block) {
  return block.components.size() > 0 && block.components(block.components.size() - 1) >= 3;
}

}  // namespace

int RowBlock::rows() const {
  switch (kind) {
    case RowKind::point:
      return static_cast<int>(selection.rows());
    case RowKind::weld:
      return 6;
    case RowKind::revolute:
    case RowKind::prismatic:
      return 5;
    case RowKind::relation:
    case RowKind::joint_limit:
      return 1;
    case RowKind::fingertip:
    case RowKind::frame_target:
      return static_cast<int>(components.size());
    case RowKind::python:
      return python_rows;
  }
  return 0;
}

double joint_limit_gap(const RowBlock& block, const Eigen::Ref<const VectorXd>& q) {
  return block.coefficients(0) * (q(block.q_indices(0)) - block.bound);
}

double joint_limit_rate(const RowBlock& block, const Eigen::Ref<const VectorXd>& v) {
  return block.coefficients(0) * v(block.v_indices(0));
}

Matrix3d jlog_rate(const Vector3d& theta, const Vector3d& theta_rate) {
  const double angle = theta.norm();
  const Matrix3d hat = pinocchio::skew(theta), hat_rate = pinocchio::skew(theta_rate);
  double coeff, coeff_rate;
  if (angle < 1e-4) {
    coeff = 1.0 / 12.0 + angle * angle / 720.0;
    coeff_rate = theta.dot(theta_rate) / 360.0;
  } else {
    const double sine = std::sin(angle), cosine = std::cos(angle);
    coeff = 1.0 / (angle * angle) - (1.0 + cosine) / (2.0 * angle * sine);
    const double dcoeff = -2.0 / (angle * angle * angle) +
                          (sine * angle * sine + (1.0 + cosine) * (sine + angle * cosine)) /
                              (2.0 * (angle * sine) * (angle * sine));
    coeff_rate = dcoeff * theta.dot(theta_rate) / angle;
  }
  return 0.5 * hat_rate + coeff_rate * hat * hat + coeff * (hat_rate * hat + hat * hat_rate);
}

Vector3d rotation_drift(const Matrix3d& rotation_a, const Matrix3d& rotation_b, const Vector3d& omega_a,
                        const Vector3d& omega_b, const Vector3d& relative_angular_drift) {
  const Matrix3d rel = rotation_b.transpose() * rotation_a;
  const Vector3d relative_omega = omega_a - omega_b;
  const Vector3d body_rate = rotation_a.transpose() * relative_omega;  // R = R_b^T R_a moves as dR/dt = R [body_rate]
  const Matrix3d jacobian = jlog(rel);
  const Vector3d theta = pinocchio::log3(rel);
  const Vector3d theta_rate = jacobian * body_rate;
  const Vector3d rotating_frame = -rotation_a.transpose() * omega_a.cross(relative_omega);
  return jlog_rate(theta, theta_rate) * body_rate + jacobian * rotating_frame +
         jacobian * (rotation_a.transpose() * relative_angular_drift);
}

void block_residual(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, const VectorXd& q,
                    double t, Eigen::Ref<VectorXd> phi) {
  if (block.kind == RowKind::joint_limit) {
    phi(0) = joint_limit_gap(block, q);
    return;
  }
  if (block.kind == RowKind::relation) {
    double value, rate, curvature;
    block.target.evaluate(t, value, rate, curvature);
    double sum = 0.0;
    for (int k = 0; k < block.coefficients.size(); ++k) sum += block.coefficients(k) * q(block.q_indices(k));
    phi(0) = sum - value;
    return;
  }
  const Sides sides = Sides::at(model, data, block, t);
  if (block.kind == RowKind::point) {
    phi.noalias() = block.selection * (sides.a().translation() - sides.b().translation());
    return;
  }
  if (block.kind == RowKind::fingertip) {
    Eigen::Matrix<double, 6, 1> full = Eigen::Matrix<double, 6, 1>::Zero();
    full.head<3>() = contact_point_residual(model, data, block.frame_a, block.frame_b);
    if (rotates(block)) full.tail<3>() = weld_residual(sides).tail<3>();
    select(block, full, phi);
    return;
  }
  const Eigen::Matrix<double, 6, 1> weld = weld_residual(sides);
  if (block.kind == RowKind::frame_target) return select(block, weld, phi);
  switch (block.kind) {
    case RowKind::weld:
      phi = weld;
      break;
    case RowKind::revolute:
      phi.head<3>() = weld.head<3>();
      phi.tail<2>().noalias() = block.selection * weld.tail<3>();
      break;
    default:  // prismatic
      phi.head<2>().noalias() = block.selection * (sides.b().rotation().transpose() * weld.head<3>());
      phi.tail<3>() = weld.tail<3>();
  }
}

void block_jacobian(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t,
                    Eigen::Ref<Eigen::MatrixXd> jacobian, Eigen::Ref<VectorXd> time_term) {
  jacobian.setZero();
  time_term.setZero();
  if (block.kind == RowKind::joint_limit) {
    jacobian(0, block.v_indices(0)) = block.coefficients(0);
    return;
  }
  if (block.kind == RowKind::relation) {
    double value, rate, curvature;
    block.target.evaluate(t, value, rate, curvature);
    for (int k = 0; k < block.coefficients.size(); ++k) jacobian(0, block.v_indices(k)) = block.coefficients(k);
    time_term(0) = -rate;
    return;
  }
  const Sides sides = Sides::at(model, data, block, t);
  if (block.kind == RowKind::point) {
    Matrix6x relative = sides.jacobian(block.frame_a);
    if (sides.moving_b()) relative -= sides.jacobian(block.frame_b);
    jacobian = block.selection * relative.topRows<3>();
    return;
  }
  if (block.kind == RowKind::fingertip) {
    Matrix6x full = Matrix6x::Zero(6, model.nv);
    full.topRows<3>() = contact_point_jacobian(model, data, block.frame_a, block.frame_b);
    if (rotates(block)) full.bottomRows<3>() = weld_jacobian(sides).bottomRows<3>();
    for (int k = 0; k < block.components.size(); ++k) jacobian.row(k) = full.row(block.components(k));
    return;
  }
  const Matrix6x weld = weld_jacobian(sides);
  if (block.kind == RowKind::frame_target) {
    for (int k = 0; k < block.components.size(); ++k) jacobian.row(k) = weld.row(block.components(k));
    return select(block, weld_time_term(sides), time_term);
  }
  switch (block.kind) {
    case RowKind::weld:
      jacobian = weld;
      break;
    case RowKind::revolute:
      jacobian.topRows<3>() = weld.topRows<3>();
      jacobian.bottomRows<2>() = block.selection * weld.bottomRows<3>();
      break;
    default: {  // prismatic: d/dq of R_b^T (p_a - p_b) = R_b^T (J_a - J_b + [p_a - p_b]x W_b)
      Eigen::MatrixXd slide = sides.jacobian(block.frame_a).topRows<3>();
      if (sides.moving_b()) {
        const Matrix6x jacobian_b = sides.jacobian(block.frame_b);
        const Vector3d gap = sides.a().translation() - sides.b().translation();
        slide += pinocchio::skew(gap) * jacobian_b.bottomRows<3>() - jacobian_b.topRows<3>();
      }
      jacobian.topRows<2>() = block.selection * (sides.b().rotation().transpose() * slide);
      jacobian.bottomRows<3>() = weld.bottomRows<3>();
    }
  }
}

void block_rate(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, const VectorXd& v,
                double t, Eigen::Ref<VectorXd> rate) {
  if (block.kind == RowKind::python) throw std::invalid_argument("block_rate: a python block's rows are Python's");
  if (block.kind == RowKind::joint_limit) {
    rate(0) = joint_limit_rate(block, v);
    return;
  }
  if (block.kind == RowKind::relation) {
    double value, target_rate, curvature;
    block.target.evaluate(t, value, target_rate, curvature);
    double sum = 0.0;
    for (int k = 0; k < block.coefficients.size(); ++k) sum += block.coefficients(k) * v(block.v_indices(k));
    rate(0) = sum - target_rate;
    return;
  }
  const Sides sides = Sides::at(model, data, block, t);
  if (block.kind == RowKind::point) {
    Vector3d linear = sides.velocity(block.frame_a).linear();
    if (sides.moving_b()) linear -= sides.velocity(block.frame_b).linear();
    rate.noalias() = block.selection * linear;
    return;
  }
  if (block.kind == RowKind::fingertip) {
    Eigen::Matrix<double, 6, 1> full = Eigen::Matrix<double, 6, 1>::Zero();
    full.head<3>() = contact_point_rate(model, data, block.frame_a, block.frame_b);
    if (rotates(block)) full.tail<3>() = weld_rate(sides).tail<3>();
    select(block, full, rate);
    return;
  }
  const Eigen::Matrix<double, 6, 1> weld = weld_rate(sides);
  if (block.kind == RowKind::frame_target) return select(block, weld, rate);
  switch (block.kind) {
    case RowKind::weld:
      rate = weld;
      break;
    case RowKind::revolute:
      rate.head<3>() = weld.head<3>();
      rate.tail<2>().noalias() = block.selection * weld.tail<3>();
      break;
    default: {  // prismatic: d/dt of R_b^T (p_a - p_b) = R_b^T (v_a - v_b + (p_a - p_b) x w_b)
      Vector3d slide = sides.velocity(block.frame_a).linear();
      if (sides.moving_b()) {
        const pinocchio::Motion velocity_b = sides.velocity(block.frame_b);
        const Vector3d gap = sides.a().translation() - sides.b().translation();
        slide += gap.cross(velocity_b.angular()) - velocity_b.linear();
      }
      rate.head<2>().noalias() = block.selection * (sides.b().rotation().transpose() * slide);
      rate.tail<3>() = weld.tail<3>();
    }
  }
}

void block_drift(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t,
                 Eigen::Ref<VectorXd> drift) {
  if (block.kind == RowKind::joint_limit) {
    drift(0) = 0.0;
    return;
  }
  if (block.kind == RowKind::relation) {
    double value, rate, curvature;
    block.target.evaluate(t, value, rate, curvature);
    drift(0) = -curvature;
    return;
  }
  const Sides sides = Sides::at(model, data, block, t);
  if (block.kind == RowKind::point) {
    Vector3d linear = sides.drift(block.frame_a).linear();
    if (sides.moving_b()) linear -= sides.drift(block.frame_b).linear();
    drift = block.selection * linear;
    return;
  }
  if (block.kind == RowKind::fingertip) {
    Eigen::Matrix<double, 6, 1> full = Eigen::Matrix<double, 6, 1>::Zero();
    full.head<3>() = contact_point_drift(model, data, block.frame_a, block.frame_b);
    if (rotates(block)) full.tail<3>() = weld_drift(sides).tail<3>();
    select(block, full, drift);
    return;
  }
  const Eigen::Matrix<double, 6, 1> weld = weld_drift(sides);
  if (block.kind == RowKind::frame_target) return select(block, weld, drift);
  switch (block.kind) {
    case RowKind::weld:
      drift = weld;
      break;
    case RowKind::revolute:
      drift.head<3>() = weld.head<3>();
      drift.tail<2>() = block.selection * weld.tail<3>();
      break;
    default: {  // prismatic: d2/dt2 of R_b^T (p_a - p_b) at zero joint acceleration, in frame b's axes
      const Vector3d gap = sides.a().translation() - sides.b().translation();
      Vector3d gap_rate = sides.velocity(block.frame_a).linear();
      Vector3d omega_b = Vector3d::Zero(), alpha_b = Vector3d::Zero();
      if (sides.moving_b()) {
        gap_rate -= sides.velocity(block.frame_b).linear();
        omega_b = sides.velocity(block.frame_b).angular();
        alpha_b = sides.drift(block.frame_b).angular();
      }
      Vector3d second = weld.head<3>() - alpha_b.cross(gap) - 2.0 * omega_b.cross(gap_rate);
      second += omega_b.cross(omega_b.cross(gap));
      drift.head<2>() = block.selection * (sides.b().rotation().transpose() * second);
      drift.tail<3>() = weld.tail<3>();
    }
  }
}

}  // namespace pinstab
