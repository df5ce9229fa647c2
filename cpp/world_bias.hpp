// The nonlinear effects h = C(q, v) v + g(q) in the world frame, from what crba's world-convention pass leaves
// in the Data (the joint Jacobians' columns J and the placements oMi), for the banded kernel.
#pragma once

#include <vector>

#include <pinocchio/spatial/force.hpp>
#include <pinocchio/spatial/motion.hpp>

#include "kernels.hpp"

namespace pinstab {

class WorldBias {
 public:
  // Whether every joint of the model has a motion subspace constant in its own frame and no bias
  // acceleration of its own (revolute, prismatic, spherical, translation, free-flyer joints): then
  // d/dt S_i = v_i x S_i, and this pass equals Pinocchio's nonLinearEffects (to rounding).
  static bool applies(const pinocchio::Model& model);

  explicit WorldBias(const pinocchio::Model& model);

  // h [N, N m] at the Data's configuration (crba with Convention::WORLD done) and velocity v [rad/s, m/s]:
  // a recursive Newton-Euler pass in the world frame at zero joint acceleration under gravity, reading the
  // Jacobian's columns instead of recomputing the joints' transforms (Pinocchio's nonLinearEffects does).
  const VectorXd& compute(const pinocchio::Model& model, const pinocchio::Data& data, const VectorXd& v);

  // after compute(): joint i's spatial velocity and its acceleration at zero joint acceleration minus gravity
  // (Pinocchio's a_gf), both at the world origin in world axes
  const pinocchio::Motion& velocity(int joint) const { return velocity_[joint]; }
  const pinocchio::Motion& acceleration(int joint) const { return acceleration_[joint]; }

 private:
  std::vector<pinocchio::Motion> velocity_, acceleration_;
  std::vector<pinocchio::Force> force_;
  VectorXd bias_;
};

}  // namespace pinstab
