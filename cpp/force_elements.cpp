#include "force_elements.hpp"

#include "group.hpp"

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>

namespace pinstab {
namespace {

// Adds the wrenches' and spring-dampers' forces (data after placements and joint Jacobians); false as
// add_force_elements.
bool add_kinematic_elements(const pinocchio::Model& model, pinocchio::Data& data, const ForceElements& elements,
                            const VectorXd& v, Eigen::Ref<VectorXd> force) {
  for (const WrenchSpec& wrench : elements.wrenches) add_wrench(model, data, wrench, force);
  for (const SpringDamperSpec& spring : elements.spring_dampers) {
    if (!add_spring_damper(model, data, spring, v, force)) return false;
  }
  return true;
}

// The wrenches' and spring-dampers' forces at (q, v) after their own placements and Jacobians pass in data.
bool kinematic_force_at(const pinocchio::Model& model, pinocchio::Data& data, const ForceElements& elements,
                        const VectorXd& q, const VectorXd& v, VectorXd& force) {
  pinocchio::computeJointJacobians(model, data, q);
  pinocchio::updateFramePlacements(model, data);
  force.setZero(model.nv);
  return add_kinematic_elements(model, data, elements, v, force);
}

}  // namespace

void add_joint_springs(const std::vector<JointSpringSpec>& springs, const VectorXd& q, const VectorXd& v,
                       Eigen::Ref<VectorXd> force) {
  for (const JointSpringSpec& spring : springs) {
    if (spring.q_index < 0) {
      for (int k = 0; k < spring.dofs.size(); ++k) force(spring.dofs(k)) += -spring.damping * v(spring.dofs(k));
      continue;
    }
    const int dof = spring.dofs(0);
    force(dof) += -(spring.stiffness * (q(spring.q_index) - spring.reference) + spring.damping * v(dof));
  }
}

void add_joint_torques(const std::vector<JointTorqueSpec>& torques, double t, Eigen::Ref<VectorXd> force) {
  for (const JointTorqueSpec& torque : torques) {
    double value, rate, curvature;
    torque.torque.evaluate(t, value, rate, curvature);
    force(torque.dof) += value;
  }
}

bool add_force_elements(const pinocchio::Model& model, pinocchio::Data& data, const ForceElements& elements, double t,
                        const VectorXd& q, const VectorXd& v, Eigen::Ref<VectorXd> force) {
  add_joint_springs(elements.springs, q, v, force);
  add_joint_torques(elements.torques, t, force);
  return add_kinematic_elements(model, data, elements, v, force);
}

bool force_element_derivatives(const pinocchio::Model& model, pinocchio::Data& data, const ForceElements& elements,
                               const VectorXd& q, const VectorXd& v, Eigen::MatrixXd& dforce_dq,
                               Eigen::MatrixXd& dforce_dv) {
  dforce_dq.setZero(model.nv, model.nv);
  dforce_dv.setZero(model.nv, model.nv);
  for (const JointSpringSpec& spring : elements.springs) {
    for (int k = 0; k < spring.dofs.size(); ++k) dforce_dv(spring.dofs(k), spring.dofs(k)) -= spring.damping;
    if (spring.q_index >= 0) dforce_dq(spring.dofs(0), spring.dofs(0)) -= spring.stiffness;
  }
  if (!elements.kinematic()) return true;
  pinocchio::computeJointJacobians(model, data, q);
  pinocchio::updateFramePlacements(model, data);
  for (const SpringDamperSpec& spring : elements.spring_dampers) {  // F = -(k (l - l0) + c u^T J v) J^T u
    const SpringLine line = spring_line(model, data, spring);
    const double length = line.difference.norm();
    if (length < kCoincidentLength) {  // the zero-rest-length spring's law is the only one had there (no damping)
      if (spring.stiffness * spring.rest_length != 0.0 || spring.damping != 0.0) return false;
      continue;
    }
    const Eigen::RowVectorXd along = (line.difference / length).transpose() * line.jacobian;  // u^T J
    dforce_dv.noalias() -= spring.damping * along.transpose() * along;
  }
  Eigen::MatrixXd kinematic;  // the wrenches' and spring-dampers' forces at v, differenced in q
  const auto force_at = [&](const VectorXd& shifted, VectorXd& force) {
    return kinematic_force_at(model, data, elements, shifted, v, force);
  };
  if (!tangent_differences(model, q, kForceDifferenceStep, force_at, kinematic)) return false;
  dforce_dq += kinematic;
  return true;
}

}  // namespace pinstab
