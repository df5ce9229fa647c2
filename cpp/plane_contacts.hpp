// The rows of plane contacts (pinstab.solvers.contact_modes.PlaneContactGeometry without a core: a body point, or a
// sphere on it, touching a plane fixed in the world or carried by a body), compiled: what ModeDynamics'
// kinematics_from_kin computed with a dozen Pinocchio calls and small-array NumPy per contact and state. The only
// place the rule is: the event-driven and the time-stepping contacts read it (round pairs, whose plane follows the
// state, stay in Python).
#pragma once

#include <vector>

#include "kernels.hpp"

namespace pinstab {

// Contact of body point `frame` (an operational frame; with radius > 0 [m] the centre of a sphere) on a plane carried
// by operational frame `plane_frame` (-1: the world): basis rows (n, t1, t2) and a point `origin` [m] of the plane,
// both in the plane's axes.
struct PlaneContact {
  int frame = 0, plane_frame = -1;
  double radius = 0.0;
  Eigen::Matrix3d basis = Eigen::Matrix3d::Identity();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
};

// The contacts at a Data's state (after a full pass: placements, joint Jacobians, motions at zero joint acceleration,
// frame placements), each in its basis: gaps [m], contact points [m, world] and in the plane's axes, velocities
// relative to the plane (k x 3) [m/s], Jacobians (3k x nv), drifts (3k) [m/s^2] (the second derivative of the point's
// position in the plane body's frame at zero acceleration) and bases (3k x 3: rows n, t1, t2 in world axes).
struct PlaneContactRows {
  VectorXd gaps;
  RowMatrix positions, local, velocities;
  RowMatrix jacobian;
  VectorXd drift;
  RowMatrix bases;
};

PlaneContactRows plane_contact_rows(const pinocchio::Model& model, pinocchio::Data& data,
                                    const std::vector<PlaneContact>& contacts, const VectorXd& v);

}  // namespace pinstab
