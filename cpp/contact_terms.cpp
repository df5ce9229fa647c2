#include "contact_terms.hpp"

#include <pinocchio/algorithm/frames.hpp>

namespace pinstab {

namespace {
constexpr auto LWA = pinocchio::LOCAL_WORLD_ALIGNED;

// d = p_o - p_f in world axes (frame placements computed)
Eigen::Vector3d difference(const pinocchio::Data& data, int object_frame, int finger_frame) {
  return data.oMf[object_frame].translation() - data.oMf[finger_frame].translation();
}
}  // namespace

Eigen::Vector3d contact_point_residual(const pinocchio::Model&, pinocchio::Data& data, int object_frame,
                                       int finger_frame) {
  return data.oMf[object_frame].rotation().transpose() * difference(data, object_frame, finger_frame);
}

Eigen::Matrix<double, 3, Eigen::Dynamic> contact_point_world_jacobian(const pinocchio::Model& model,
                                                                      pinocchio::Data& data, int object_frame,
                                                                      int finger_frame) {
  Eigen::Matrix<double, 6, Eigen::Dynamic> object(6, model.nv), finger(6, model.nv);
  object.setZero();
  finger.setZero();
  pinocchio::getFrameJacobian(model, data, object_frame, LWA, object);
  pinocchio::getFrameJacobian(model, data, finger_frame, LWA, finger);
  const Eigen::Vector3d d = difference(data, object_frame, finger_frame);
  Eigen::Matrix<double, 3, Eigen::Dynamic> linear = object.topRows<3>() - finger.topRows<3>();
  for (int j = 0; j < model.nv; ++j) linear.col(j) += d.cross(Eigen::Vector3d(object.block<3, 1>(3, j)));
  return linear;
}

Eigen::MatrixXd contact_point_jacobian(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                       int finger_frame) {
  return data.oMf[object_frame].rotation().transpose() *
         contact_point_world_jacobian(model, data, object_frame, finger_frame);
}

Eigen::Vector3d contact_point_world_rate(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                         int finger_frame) {
  const pinocchio::Motion object = pinocchio::getFrameVelocity(model, data, object_frame, LWA);
  const pinocchio::Motion finger = pinocchio::getFrameVelocity(model, data, finger_frame, LWA);
  const Eigen::Vector3d d = difference(data, object_frame, finger_frame);
  return object.linear() - finger.linear() + d.cross(object.angular());
}

Eigen::Vector3d contact_point_rate(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                   int finger_frame) {
  return data.oMf[object_frame].rotation().transpose() *
         contact_point_world_rate(model, data, object_frame, finger_frame);
}

Eigen::Vector3d contact_point_drift(const pinocchio::Model& model, pinocchio::Data& data, int object_frame,
                                    int finger_frame) {
  const pinocchio::SE3& placement = data.oMf[object_frame];
  const Eigen::Vector3d d = difference(data, object_frame, finger_frame);
  const pinocchio::Motion object = pinocchio::getFrameVelocity(model, data, object_frame, LWA);
  const pinocchio::Motion finger = pinocchio::getFrameVelocity(model, data, finger_frame, LWA);
  const pinocchio::Motion object_acc = pinocchio::getFrameClassicalAcceleration(model, data, object_frame, LWA);
  const pinocchio::Motion finger_acc = pinocchio::getFrameClassicalAcceleration(model, data, finger_frame, LWA);
  const Eigen::Vector3d w = object.angular();
  const Eigen::Vector3d x = w.cross(d) - 2.0 * (object.linear() - finger.linear());  // w x d - 2 d'
  const Eigen::Vector3d turning =
      object_acc.linear() - finger_acc.linear() + w.cross(x) - object_acc.angular().cross(d);
  return placement.rotation().transpose() * turning;
}

}  // namespace pinstab
