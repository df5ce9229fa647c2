#include "core_rows.hpp"

#include "contact_terms.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/spatial/explog.hpp>
#include <pinocchio/spatial/skew.hpp>

namespace pinstab {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Six = Eigen::Matrix<double, 6, 1>;
using Matrix6x = Eigen::Matrix<double, 6, Eigen::Dynamic>;
constexpr auto LWA = pinocchio::LOCAL_WORLD_ALIGNED;

// The two sides of a frame block: placements, and (on demand; side b's and the motions computed once) Jacobians,
// velocities and drift accelerations in LOCAL_WORLD_ALIGNED; side b is the world placement `world` when frame_b < 0 (zero Jacobian; fixed,
// or a frame_target's moving one with its velocity and acceleration, see at()).
struct Sides {
  const pinocchio::Model& model;
  pinocchio::Data& data;
  const RowBlock& block;
  pinocchio::SE3 world = block.world_b;
  pinocchio::Motion world_velocity = pinocchio::Motion::Zero(), world_acceleration = pinocchio::Motion::Zero();
  std::optional<Matrix6x> jacobian_b;
  std::optional<pinocchio::Motion> velocity_a, velocity_b, drift_a, drift_b;

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
  // R_b^T R_a
  Matrix3d relative_rotation() const { return b().rotation().transpose() * a().rotation(); }
  Matrix6x frame_jacobian(int frame) const {
    Matrix6x jacobian = Matrix6x::Zero(6, model.nv);
    pinocchio::getFrameJacobian(model, data, frame, LWA, jacobian);
    return jacobian;
  }
  const Matrix6x& jacobian_of_b() {
    if (!jacobian_b) jacobian_b = frame_jacobian(block.frame_b);
    return *jacobian_b;
  }
  const pinocchio::Motion& velocity_of_a() {
    if (!velocity_a) velocity_a = pinocchio::getFrameVelocity(model, data, block.frame_a, LWA);
    return *velocity_a;
  }
  // side b's velocity: its frame's, or the world side's motion
  const pinocchio::Motion& velocity_of_b() {
    if (!moving_b()) return world_velocity;
    if (!velocity_b) velocity_b = pinocchio::getFrameVelocity(model, data, block.frame_b, LWA);
    return *velocity_b;
  }
  const pinocchio::Motion& drift_of_a() {
    if (!drift_a) drift_a = pinocchio::getFrameClassicalAcceleration(model, data, block.frame_a, LWA);
    return *drift_a;
  }
  const pinocchio::Motion& drift_of_b() {
    if (!moving_b()) return world_acceleration;
    if (!drift_b) drift_b = pinocchio::getFrameClassicalAcceleration(model, data, block.frame_b, LWA);
    return *drift_b;
  }
};

Matrix3d jlog(const Matrix3d& rotation) {
  Matrix3d jacobian;
  pinocchio::Jlog3(rotation, jacobian);
  return jacobian;
}

// The quantities the kinds' rows select from (kind_rows), one class per quantity the callers need: a relation's row,
// a joint limit's, and the relative motion of a frame block's two sides --
//   linear:  the points' p_a - p_b (world axes),
//   angular: log3(R_b^T R_a),
//   slide:   p_a - p_b as seen turning with side b (its rows R_b^T slide: R_b^T (p_a - p_b) and its derivatives),
//   contact: a fingertip's point rows (cpp/contact_terms.hpp),
// each as the value (Residual), its Jacobian (Jacobian) with the time term g_t (TimeTerm), its rate G v + g_t (Rate)
// and its drift at zero joint acceleration (Drift). `Full` holds a weld's six values (one column, or nv).

// A joint relation's row: sum_k c_k x(indices_k) less the target's value (order 0: x = q) or rate (order 1: x = v)
// at t [s]: its residual [rad or m] or its rate G v + g_t [rad/s or m/s].
double relation_row(const RowBlock& block, const VectorXd& x, const VectorXi& indices, double t, int order) {
  double value, rate, curvature;
  block.target.evaluate(t, value, rate, curvature);
  double sum = 0.0;
  for (int k = 0; k < block.coefficients.size(); ++k) sum += block.coefficients(k) * x(indices(k));
  return sum - (order == 0 ? value : rate);
}

// phi [m or rad] (after placements)
struct Residual {
  using Full = Six;
  Sides& sides;
  const VectorXd& q;
  double t;
  Full full() const { return Full::Zero(); }
  void relation(Eigen::Ref<VectorXd> rows) const {
    rows(0) = relation_row(sides.block, q, sides.block.q_indices, t, 0);
  }
  void joint_limit(Eigen::Ref<VectorXd> rows) const { rows(0) = joint_limit_gap(sides.block, q); }
  Vector3d linear() const { return sides.a().translation() - sides.b().translation(); }
  Vector3d angular() const { return pinocchio::log3(sides.relative_rotation()); }
  Vector3d slide() const { return linear(); }
  Vector3d contact() const {
    return contact_point_residual(sides.model, sides.data, sides.block.frame_a, sides.block.frame_b);
  }
};

// G [m/rad or 1] (after joint Jacobians and placements)
struct Jacobian {
  using Full = Matrix6x;
  Sides& sides;
  double t;
  std::optional<Matrix6x> relative_;
  Full full() const { return Matrix6x::Zero(6, sides.model.nv); }
  // J_a - J_b (6 x nv), LOCAL_WORLD_ALIGNED
  const Matrix6x& relative() {
    if (!relative_) {
      relative_ = sides.frame_jacobian(sides.block.frame_a);
      if (sides.moving_b()) *relative_ -= sides.jacobian_of_b();
    }
    return *relative_;
  }
  void relation(Eigen::Ref<Eigen::MatrixXd> rows) const {
    const RowBlock& block = sides.block;
    for (int k = 0; k < block.coefficients.size(); ++k) rows(0, block.v_indices(k)) = block.coefficients(k);
  }
  void joint_limit(Eigen::Ref<Eigen::MatrixXd> rows) const {
    rows(0, sides.block.v_indices(0)) = sides.block.coefficients(0);
  }
  auto linear() { return relative().topRows<3>(); }
  Eigen::Matrix<double, 3, Eigen::Dynamic> angular() {
    const Matrix3d& rotation_a = sides.a().rotation();
    return jlog(sides.relative_rotation()) * rotation_a.transpose() * relative().bottomRows<3>();
  }
  // d/dq of (p_a - p_b) turning with b: J_a - J_b + [p_a - p_b]x W_b
  Eigen::MatrixXd slide() {
    Eigen::MatrixXd slide = sides.frame_jacobian(sides.block.frame_a).topRows<3>();
    if (sides.moving_b()) {
      const Matrix6x& jacobian_b = sides.jacobian_of_b();
      const Vector3d gap = sides.a().translation() - sides.b().translation();
      slide += pinocchio::skew(gap) * jacobian_b.bottomRows<3>() - jacobian_b.topRows<3>();
    }
    return slide;
  }
  Eigen::MatrixXd contact() const {
    return contact_point_jacobian(sides.model, sides.data, sides.block.frame_a, sides.block.frame_b);
  }
};

// g_t [m/s or rad/s]: a relation's target and a frame_target's side b move in time (block_jacobian asks no other
// kind; their side b is fixed)
struct TimeTerm {
  using Full = Six;
  Sides& sides;
  double t;
  Full full() const { return Full::Zero(); }
  void relation(Eigen::Ref<VectorXd> rows) const {
    double value, rate, curvature;
    sides.block.target.evaluate(t, value, rate, curvature);
    rows(0) = -rate;
  }
  void joint_limit(Eigen::Ref<VectorXd>) const {}
  // side b's world motion through the rows: -(v_b, Jlog3(R_b^T R_a) R_a^T w_b)
  Vector3d linear() const { return -sides.world_velocity.linear(); }
  Vector3d angular() const {
    return -(jlog(sides.relative_rotation()) * (sides.a().rotation().transpose() * sides.world_velocity.angular()));
  }
  Vector3d slide() const { return Vector3d::Zero(); }
  Vector3d contact() const { return Vector3d::Zero(); }
};

// g = G v + g_t [m/s or rad/s] without forming G (after velocities and placements)
struct Rate {
  using Full = Six;
  Sides& sides;
  const VectorXd& v;
  double t;
  Full full() const { return Full::Zero(); }
  void relation(Eigen::Ref<VectorXd> rows) const {
    rows(0) = relation_row(sides.block, v, sides.block.v_indices, t, 1);
  }
  void joint_limit(Eigen::Ref<VectorXd> rows) const { rows(0) = joint_limit_rate(sides.block, v); }
  Vector3d linear() { return sides.velocity_of_a().linear() - sides.velocity_of_b().linear(); }
  // Jlog3(R_b^T R_a) R_a^T (w_a - w_b)
  Vector3d angular() {
    const Vector3d angular = sides.velocity_of_a().angular() - sides.velocity_of_b().angular();
    return jlog(sides.relative_rotation()) * (sides.a().rotation().transpose() * angular);
  }
  // d/dt of (p_a - p_b) turning with b: v_a - v_b + (p_a - p_b) x w_b
  Vector3d slide() {
    Vector3d slide = sides.velocity_of_a().linear();
    if (sides.moving_b()) {
      const pinocchio::Motion& velocity_b = sides.velocity_of_b();
      const Vector3d gap = sides.a().translation() - sides.b().translation();
      slide += gap.cross(velocity_b.angular()) - velocity_b.linear();
    }
    return slide;
  }
  Vector3d contact() const {
    return contact_point_rate(sides.model, sides.data, sides.block.frame_a, sides.block.frame_b);
  }
};

// gamma0 [m/s^2 or rad/s^2] (after a full pass at zero joint acceleration and placements)
struct Drift {
  using Full = Six;
  Sides& sides;
  double t;
  Full full() const { return Full::Zero(); }
  void relation(Eigen::Ref<VectorXd> rows) const {
    double value, rate, curvature;
    sides.block.target.evaluate(t, value, rate, curvature);
    rows(0) = -curvature;
  }
  void joint_limit(Eigen::Ref<VectorXd> rows) const { rows(0) = 0.0; }
  Vector3d linear() { return sides.drift_of_a().linear() - sides.drift_of_b().linear(); }
  Vector3d angular() {
    const Vector3d relative_angular_drift = sides.drift_of_a().angular() - sides.drift_of_b().angular();
    return rotation_drift(sides.a().rotation(), sides.b().rotation(), sides.velocity_of_a().angular(),
                          sides.velocity_of_b().angular(), relative_angular_drift);
  }
  // d2/dt2 of (p_a - p_b) turning with b at zero joint acceleration
  Vector3d slide() {
    const Vector3d gap = sides.a().translation() - sides.b().translation();
    Vector3d gap_rate = sides.velocity_of_a().linear();
    Vector3d omega_b = Vector3d::Zero(), alpha_b = Vector3d::Zero();
    if (sides.moving_b()) {
      gap_rate -= sides.velocity_of_b().linear();
      omega_b = sides.velocity_of_b().angular();
      alpha_b = sides.drift_of_b().angular();
    }
    Vector3d second = linear() - alpha_b.cross(gap) - 2.0 * omega_b.cross(gap_rate);
    second += omega_b.cross(omega_b.cross(gap));
    return second;
  }
  Vector3d contact() const {
    return contact_point_drift(sides.model, sides.data, sides.block.frame_a, sides.block.frame_b);
  }
};

// The components of a weld's six values (a fingertip's or a frame_target's rows).
template <typename Full, typename Rows>
void select(const RowBlock& block, const Full& full, Rows& rows) {
  for (int k = 0; k < block.components.size(); ++k) rows.row(k) = full.row(block.components(k));
}

// A fingertip block with rotation rows (soft-finger, rigid): the last component is a moment's.
bool rotates(const RowBlock& block) {
  return block.components.size() > 0 && block.components(block.components.size() - 1) >= 3;
}

// Each kind's rows, the one place they are defined (docs in core_rows.hpp), for any of the quantities above: rows
// (a segment, or the rows x nv block of G) written whole.
template <typename Quantity, typename Rows>
void kind_rows(const RowBlock& block, Quantity& x, Rows rows) {
  switch (block.kind) {
    case RowKind::relation:
      return x.relation(rows);
    case RowKind::joint_limit:
      return x.joint_limit(rows);
    case RowKind::point:
      rows.noalias() = block.selection * x.linear();
      return;
    case RowKind::weld:
      rows.template topRows<3>() = x.linear();
      rows.template bottomRows<3>() = x.angular();
      return;
    case RowKind::revolute:
      rows.template topRows<3>() = x.linear();
      rows.template bottomRows<2>().noalias() = block.selection * x.angular();
      return;
    case RowKind::prismatic:
      rows.template topRows<2>().noalias() = block.selection * (x.sides.b().rotation().transpose() * x.slide());
      rows.template bottomRows<3>() = x.angular();
      return;
    case RowKind::fingertip: {
      typename Quantity::Full full = x.full();
      full.template topRows<3>() = x.contact();
      if (rotates(block)) full.template bottomRows<3>() = x.angular();
      return select(block, full, rows);
    }
    case RowKind::frame_target: {
      typename Quantity::Full full = x.full();
      full.template topRows<3>() = x.linear();
      full.template bottomRows<3>() = x.angular();
      return select(block, full, rows);
    }
    case RowKind::python:
      break;
  }
  throw std::invalid_argument("core rows: a python block's rows are Python's");
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
  Sides sides = Sides::at(model, data, block, t);
  Residual residual{sides, q, t};
  kind_rows(block, residual, phi);
}

void block_jacobian(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t,
                    Eigen::Ref<Eigen::MatrixXd> jacobian, Eigen::Ref<VectorXd> time_term) {
  jacobian.setZero();
  time_term.setZero();
  Sides sides = Sides::at(model, data, block, t);
  Jacobian rows{sides, t};
  kind_rows(block, rows, jacobian);
  if (block.kind == RowKind::relation || block.kind == RowKind::frame_target) {  // the kinds that move in time
    TimeTerm term{sides, t};
    kind_rows(block, term, time_term);
  }
}

void block_rate(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, const VectorXd& v,
                double t, Eigen::Ref<VectorXd> rate) {
  Sides sides = Sides::at(model, data, block, t);
  Rate rows{sides, v, t};
  kind_rows(block, rows, rate);
}

void block_drift(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t,
                 Eigen::Ref<VectorXd> drift) {
  Sides sides = Sides::at(model, data, block, t);
  Drift rows{sides, t};
  kind_rows(block, rows, drift);
}

}  // namespace pinstab
