#include "joint_actuators.hpp"

#include <algorithm>

namespace pinstab {

Eigen::VectorXd JointActuators::forces(const Eigen::VectorXd& q, const Eigen::VectorXd& qdot, double t) const {
  Eigen::VectorXd u, rate, curvature;
  controls.evaluate(t, u, rate, curvature);
  Eigen::VectorXd f(gear.size());
  for (Eigen::Index i = 0; i < gear.size(); ++i) {
    const double clipped = std::min(std::max(u(i), ctrlrange(0, i)), ctrlrange(1, i));
    const double force =
        gain(i) * clipped + bias(0, i) + bias(1, i) * gear(i) * q(i) + bias(2, i) * gear(i) * qdot(i);
    f(i) = std::min(std::max(force, forcerange(0, i)), forcerange(1, i));
  }
  return f;
}

Eigen::VectorXd JointActuators::generalized_force(const Eigen::VectorXd& q, const Eigen::VectorXd& v, double t) const {
  const Eigen::Index count = gear.size();
  Eigen::VectorXd joint_q(count), joint_v(count);
  for (Eigen::Index i = 0; i < count; ++i) {
    joint_q(i) = positions(i) < 0 ? 0.0 : q(positions(i));
    joint_v(i) = v(dofs(i));
  }
  const Eigen::VectorXd f = forces(joint_q, joint_v, t);
  Eigen::VectorXd tau = Eigen::VectorXd::Zero(nv);
  for (Eigen::Index i = 0; i < count; ++i) tau(dofs(i)) += gear(i) * f(i);
  return tau;
}

}  // namespace pinstab
