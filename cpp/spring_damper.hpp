// The spring-damper force element (pinstab.forces.spring_damper.SpringDamper calls these; the core kernel,
// cpp/core_kernel.cpp, adds them to its forces): a linear spring-damper between two frames' origins, or between a
// frame's origin and a fixed world point.
#pragma once

#include <optional>

#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include "kernels.hpp"

namespace pinstab {

// [m] the length below which the line's direction u is not defined (the points coincide)
constexpr double kCoincidentLength = 1e-12;

// A spring-damper: on point a (frame_a's origin) F = -(k (l - l0) + c dl/dt) u with u = (p_a - p_b) / l, on point b
// (frame_b's origin; frame_b < 0: the world point point_b [m]) -F. Stiffness k [N/m], damping c [N s/m], rest length
// l0 [m].
struct SpringDamperSpec {
  int frame_a = -1, frame_b = -1;
  Eigen::Vector3d point_b = Eigen::Vector3d::Zero();
  double stiffness = 0.0, damping = 0.0, rest_length = 0.0;
};

// The line between the points at a state: p_a - p_b [m] and its Jacobian J_a - J_b (3 x nv: the frames'
// LOCAL_WORLD_ALIGNED linear rows) [m/rad, 1].
struct SpringLine {
  Eigen::Vector3d difference;
  Eigen::Matrix<double, 3, Eigen::Dynamic> jacobian;
};

// The spring-damper's terms at (q, v): its length l [m], length rate dl/dt = u . (J_a - J_b) v [m/s] (0 where the
// points coincide) and generalized force (J_a - J_b)^T F [N, N m] (nv,).
struct SpringDamperTerms {
  double length = 0.0, rate = 0.0;
  VectorXd force;
};

// The line from a Data after placements and joint Jacobians (computeJointJacobians or computeAllTerms, then
// updateFramePlacements).
SpringLine spring_line(const pinocchio::Model& model, pinocchio::Data& data, const SpringDamperSpec& spring);

// The terms at velocity v from the line. Where the points coincide (l < kCoincidentLength) the law is kept where it
// needs no direction (k l0 = 0 and c = 0: F = -k (p_a - p_b), a zero-rest-length spring) and is otherwise undefined:
// nullopt (the element refuses the state, naming itself).
std::optional<SpringDamperTerms> spring_damper_terms(const SpringDamperSpec& spring, const SpringLine& line,
                                                      const VectorXd& v);

// Adds the generalized force at (q, v) to force (a Data as for spring_line); false where it is undefined (see
// spring_damper_terms): nothing is added.
bool add_spring_damper(const pinocchio::Model& model, pinocchio::Data& data, const SpringDamperSpec& spring,
                       const VectorXd& v, Eigen::Ref<VectorXd> force);

}  // namespace pinstab
