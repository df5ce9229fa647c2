// The point rows of a fingertip contact (pinstab.constraints.grasp_contacts.FingertipContact), compiled: what its
// Python computed with a dozen Pinocchio calls and small-array NumPy per contact and evaluation.
#pragma once

#include "kernels.hpp"

namespace pinstab {

// Rows R^T (p_o - p_f) between the object's frame o (rotation R) and the fingertip's frame f, read from a Data
// after a kinematics pass (frame placements) ...
Eigen::Vector3d contact_point_residual(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                       int finger_frame);
// ... their Jacobian R^T (J_o - J_f + [p_o - p_f]x W_o) (3 x nv; linear J, angular W in
// LOCAL_WORLD_ALIGNED; needs the joint Jacobians and frame placements) ...
Eigen::MatrixXd contact_point_jacobian(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                       int finger_frame);
// ... the same in world axes, J_o - J_f + [p_o - p_f]x W_o (3 x nv): the velocity of the object's material point at
// the finger frame's origin relative to the finger's (pinstab.constraints.rolling_contacts: minus its J_w) ...
Eigen::Matrix<double, 3, Eigen::Dynamic> contact_point_world_jacobian(const pinocchio::Model& model,
                                                                      pinocchio::Data& data, int object_frame,
                                                                      int finger_frame);
// ... their rate R^T (v_o - v_f + (p_o - p_f) x w_o) (velocities v, w in LOCAL_WORLD_ALIGNED; needs velocities and
// frame placements: forwardKinematics(q, v), updateFramePlacements), the Jacobian's product with v without forming it ...
Eigen::Vector3d contact_point_rate(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                   int finger_frame);
// ... the same in world axes, v_o - v_f + (p_o - p_f) x w_o [m/s] (the world Jacobian's product with v) ...
Eigen::Vector3d contact_point_world_rate(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                         int finger_frame);
// ... and their second derivative at zero joint acceleration, R^T (a_o - a_f + w x (w x d - 2 d') - alpha x d)
// with d = p_o - p_f (needs a full pass: velocities and accelerations at zero joint acceleration).
Eigen::Vector3d contact_point_drift(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                    int finger_frame);

}  // namespace pinstab
