// The standard constraint rows, compiled once: each block's residual phi, Jacobian G (with its explicit time term
// g_t of g = G v + g_t) and drift gamma0 of G a + gamma0 = 0 (docs/mathematics.md section 1). pinstab's Python
// constraint classes of these kinds (pinstab.constraints.loops, joint_closures, joint_relation, frame_targets,
// grasp_contacts) and the frame form of pinstab.forces.joint_spring call these same functions (pinstab.kernels), and
// the core kernel (cpp/core_kernel.hpp) evaluates its rows with them.
#pragma once

#include <vector>

#include <pinocchio/spatial/se3.hpp>

#include "grasp_forces.hpp"
#include "kernels.hpp"
#include "targets.hpp"

namespace pinstab {

// point: S (p_a - p_b), S the rows x 3 selection (the identity; planar-point: the plane's two axes), world axes.
// weld: the points (3 rows, world axes), then log3(R_b^T R_a) (3 rows).
// revolute: the points, then `across` (2 x 3) times log3(R_b^T R_a): a turn about the axis is free.
// prismatic: across R_b^T (p_a - p_b) (2 rows), then log3(R_b^T R_a): a slide along the axis is free.
// relation: c . q[q_indices] - c(t) on 1-DOF joints (one row).
// fingertip: the contact frame C on the object (frame_a) and its copy on the fingertip (frame_b): the components of
// (R_C^T (p_a - p_b), log3(R_b^T R_a)) its contact model transmits (pinstab.constraints.grasp_contacts).
// python: rows a Python block gives at each evaluation (the core kernel's PythonPart), not computed here.
// frame_target: a weld's rows (the `components` of its six) between frame_a and a side b moving in time, b's
// placement (p(t), exp(turn(t) axis) R_0): p(t) the 3-component `path` (none: world_b's translation), turn(t) the
// `target` [rad] about the fixed world `axis`, R_0 world_b's rotation; b's velocity (p', turn' axis) gives the time
// term g_t and its acceleration (p'', turn'' axis) the drift (pinstab.constraints.frame_targets).
// joint_limit: an active joint limit, sign (q[q_indices(0)] - bound) (one row; Jacobian sign e_i on v_indices(0),
// no time term, drift 0), sign = coefficients(0): +1 a lower limit, -1 an upper one (pinstab.constraints.joint_limits).
enum class RowKind {
  point = 0,
  weld = 1,
  revolute = 2,
  prismatic = 3,
  relation = 4,
  fingertip = 5,
  python = 6,
  frame_target = 7,
  joint_limit = 8
};

struct RowBlock {
  RowKind kind = RowKind::point;
  int frame_a = -1, frame_b = -1;                            // frame ids; frame_b < 0: the fixed world_b
  pinocchio::SE3 world_b = pinocchio::SE3::Identity();       // side b's world placement when it is the world
  Eigen::MatrixXd selection;                                 // point: rows x 3; revolute, prismatic: across (2 x 3)
  VectorXd coefficients;                                     // relation: c
  VectorXi q_indices, v_indices;                             // relation: its joints' coordinates
  Target target;                                             // relation: c(t); frame_target: turn(t) [rad]
  Targets path;                                              // frame_target: p(t) [m] (3 components, or none)
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();           // frame_target: the turn's world axis (unit)
  VectorXi components;                                       // fingertip: of (fx, fy, fz, mx, my, mz) in C;
                                                             // frame_target: of the weld's six rows
  ContactModel contact_model = ContactModel::rigid;          // fingertip: what it carries (limits)
  double mu = 0.0, torsion = 0.0;                            // fingertip: friction [-], torsion [m]
  bool holonomic = true;                                     // false: velocity-level rows (Baumgarte's Kd / 2)
  int python_rows = 0;                                       // python: its row count
  double bound = 0.0;                                        // joint_limit: the bound [rad or m]
  int rows() const;
};

// Each function reads a Data of `model` after the pass it names; `jacobian` and `time_term` are written on the
// block's rows only (jacobian: rows x nv, every entry written).
// phi [m or rad]: after placements (forwardKinematics, updateFramePlacements).
void block_residual(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block,
                    const VectorXd& q, double t, Eigen::Ref<VectorXd> phi);
// G [m/rad or 1] and g_t [m/s or rad/s]: after joint Jacobians and placements (computeJointJacobians,
// updateFramePlacements).
void block_jacobian(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t,
                    Eigen::Ref<Eigen::MatrixXd> jacobian, Eigen::Ref<VectorXd> time_term);
// g = G v + g_t [m/s or rad/s] without forming G (O(rows)): after velocities and placements (forwardKinematics(q, v),
// updateFramePlacements; a relation reads v only). Not for python blocks (their rows are Python's).
void block_rate(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, const VectorXd& v,
                double t, Eigen::Ref<VectorXd> rate);
// gamma0 [m/s^2 or rad/s^2]: after a full pass (computeAllTerms: velocities, accelerations at zero joint acceleration,
// Jacobians) and placements.
void block_drift(const pinocchio::Model& model, pinocchio::Data& data, const RowBlock& block, double t,
                 Eigen::Ref<VectorXd> drift);

// A joint_limit block's gap sign (q_i - bound) [rad or m] (positive inside the range) and its rate sign v_i [rad/s
// or m/s]: its residual and G v (block_residual, block_rate) and pinstab's JointLimit.gap / speed.
double joint_limit_gap(const RowBlock& block, const Eigen::Ref<const VectorXd>& q);
double joint_limit_rate(const RowBlock& block, const Eigen::Ref<const VectorXd>& v);

// d/dt Jlog3(theta(t)) for theta' = theta_rate: Jlog3(theta) = E + [theta]/2 + c(|theta|) [theta]^2,
// c(x) = 1/x^2 - (1 + cos x) / (2 x sin x) (a series below 1e-4 rad).
Eigen::Matrix3d jlog_rate(const Eigen::Vector3d& theta, const Eigen::Vector3d& theta_rate);
// gamma0 of the rows log3(R_b^T R_a) [rad/s^2]: omegas [rad/s] and alpha_a - alpha_b at zero joint acceleration
// [rad/s^2] in world axes.
Eigen::Vector3d rotation_drift(const Eigen::Matrix3d& rotation_a, const Eigen::Matrix3d& rotation_b,
                               const Eigen::Vector3d& omega_a, const Eigen::Vector3d& omega_b,
                               const Eigen::Vector3d& relative_angular_drift);

}  // namespace pinstab
