// The compiled force elements that read no constraint rows (joint springs, joint torques, constant wrenches,
// spring-dampers), summed in one place for every kernel that takes them (the core kernel, cpp/core_kernel.cpp, and
// the native one, cpp/native_kernel.cpp), with their derivatives in q and v for the native kernel's Jacobians.
#pragma once

#include <vector>

#include "grasp_forces.hpp"
#include "kernels.hpp"
#include "spring_damper.hpp"
#include "targets.hpp"

namespace pinstab {

// pinstab.forces.joint_spring.JointSpring in joint form: tau[dofs] = -k (q[q_index] - reference) - c v[dofs] on a
// 1-DOF joint of one coordinate; -c v[dofs] (damping only) on a multi-DOF one (q_index < 0).
struct JointSpringSpec {
  VectorXi dofs;
  int q_index = -1;
  double stiffness = 0.0, reference = 0.0, damping = 0.0;
};

// Adds the springs' generalized forces [N, N m] at (q, v) to force.
void add_joint_springs(const std::vector<JointSpringSpec>& springs, const VectorXd& q, const VectorXd& v,
                       Eigen::Ref<VectorXd> force);

// pinstab.forces.joint_torque.JointTorque: tau[dof] = torque(t) [N m or N], its table as a compiled target (linear
// between its points, held at its ends; a constant: one point).
struct JointTorqueSpec {
  int dof = -1;
  Target torque;
};

// Adds the torques at t [s] to force.
void add_joint_torques(const std::vector<JointTorqueSpec>& torques, double t, Eigen::Ref<VectorXd> force);

// The elements (pinstab.forces.*.compiled_form of kinds joint-spring, joint-torque, wrench, spring-damper).
struct ForceElements {
  std::vector<JointSpringSpec> springs;
  std::vector<WrenchSpec> wrenches;
  std::vector<SpringDamperSpec> spring_dampers;
  std::vector<JointTorqueSpec> torques;

  bool empty() const { return springs.empty() && wrenches.empty() && spring_dampers.empty() && torques.empty(); }
  // whether some element reads the frames' placements and Jacobians (a wrench, a spring-damper)
  bool kinematic() const { return !wrenches.empty() || !spring_dampers.empty(); }
};

// Adds the elements' generalized forces [N, N m] at (t [s], q, v) to force, springs, torques, wrenches, then
// spring-dampers, each in its order; data after placements and joint Jacobians where kinematic() (computeAllTerms or
// computeJointJacobians, then updateFramePlacements). False where a spring-damper has no direction (its points
// coincide, spring_damper_terms): the sum is then incomplete and not to be used.
bool add_force_elements(const pinocchio::Model& model, pinocchio::Data& data, const ForceElements& elements, double t,
                        const VectorXd& q, const VectorXd& v, Eigen::Ref<VectorXd> force);

// [m or rad] the central differences' step in the tangent space of q of the kinematic elements' forces
constexpr double kForceDifferenceStep = 1e-6;

// The derivatives of the elements' forces at (q, v) (the torques', functions of t alone, are zero): dforce_dq
// [N/m, N m/rad] against q (+) dq (dq in the tangent space at q) and dforce_dv [N s/m, N m s/rad], nv x nv each
// (overwritten). Joint springs and dampers analytic (diagonal), a spring-damper's damping in v analytic
// (-c J^T u u^T J); the dependence on q of wrenches and spring-dampers (their Jacobians and lines) by central
// differences of those elements' forces alone over pinocchio::integrate steps of kForceDifferenceStep (2 nv
// kinematics passes). data is overwritten (placements and Jacobians at the shifted configurations); false where a
// spring-damper has no direction at q or a shifted configuration.
bool force_element_derivatives(const pinocchio::Model& model, pinocchio::Data& data, const ForceElements& elements,
                               const VectorXd& q, const VectorXd& v, Eigen::MatrixXd& dforce_dq,
                               Eigen::MatrixXd& dforce_dv);

}  // namespace pinstab
