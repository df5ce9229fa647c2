// MuJoCo's affine actuators on 1-DOF joints (pinstab/forces/joint_actuator.py, the only place of their law): with the
// control u(t) of each actuator's time table clipped to its ctrlrange, the length l = gear q and velocity ldot = gear
// qdot, the actuator force f = gain u + bias_0 + bias_1 l + bias_2 ldot clipped to its forcerange; its joint gets
// gear f. Evaluated for several actuators at once (a model's): one evaluation of their tables, one pass of the law.
#pragma once

#include <Eigen/Core>

#include "targets.hpp"

namespace pinstab {

struct JointActuators {
  Targets controls;           // u(t), one component per actuator
  Eigen::VectorXi dofs;       // each actuator's joint's velocity index
  Eigen::VectorXi positions;  // its joint's configuration index; -1: bias_1 is zero, the position is not read
  Eigen::VectorXd gear, gain;
  Eigen::Matrix<double, 3, Eigen::Dynamic> bias;         // bias_0, bias_1, bias_2 per actuator
  Eigen::Matrix<double, 2, Eigen::Dynamic> ctrlrange;    // low, high [control units]
  Eigen::Matrix<double, 2, Eigen::Dynamic> forcerange;   // low, high [N or N m]
  int nv = 0;

  // The actuator forces f [N or N m] at the joints' positions q [rad or m] and velocities qdot (one per actuator) at
  // time t [s].
  Eigen::VectorXd forces(const Eigen::VectorXd& q, const Eigen::VectorXd& qdot, double t) const;
  // Their generalized force (nv) [N or N m] at the model's configuration q and velocity v: gear f added to each
  // actuator's coordinate, in the actuators' order, from zero.
  Eigen::VectorXd generalized_force(const Eigen::VectorXd& q, const Eigen::VectorXd& v, double t) const;
};

}  // namespace pinstab
