#include "plane_contacts.hpp"

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/spatial/skew.hpp>

namespace pinstab {

namespace {
constexpr auto LWA = pinocchio::LOCAL_WORLD_ALIGNED;
using Rows3 = Eigen::Matrix<double, 3, Eigen::Dynamic>;
using Jacobian6 = Eigen::Matrix<double, 6, Eigen::Dynamic>;

Jacobian6 frame_jacobian(const pinocchio::Model& model, pinocchio::Data& data, int frame) {
  Jacobian6 jacobian = Jacobian6::Zero(6, model.nv);
  pinocchio::getFrameJacobian(model, data, static_cast<pinocchio::FrameIndex>(frame), LWA, jacobian);
  return jacobian;
}
}  // namespace

PlaneContactRows plane_contact_rows(const pinocchio::Model& model, pinocchio::Data& data,
                                    const std::vector<PlaneContact>& contacts, const VectorXd& v) {
  const Eigen::Index k = static_cast<Eigen::Index>(contacts.size());
  PlaneContactRows rows{VectorXd(k), RowMatrix(k, 3), RowMatrix(k, 3), RowMatrix(k, 3),
                        RowMatrix(3 * k, model.nv), VectorXd(3 * k), RowMatrix(3 * k, 3)};
  for (Eigen::Index i = 0; i < k; ++i) {
    const PlaneContact& contact = contacts[static_cast<std::size_t>(i)];
    const bool carried = contact.plane_frame >= 0;
    const pinocchio::SE3& plane = data.oMf[carried ? contact.plane_frame : 0];
    const Eigen::Matrix3d basis = carried ? Eigen::Matrix3d(contact.basis * plane.rotation().transpose()) : contact.basis;
    const Eigen::Vector3d normal = basis.row(0).transpose();
    const Jacobian6 jacobian = frame_jacobian(model, data, contact.frame);
    const pinocchio::Motion acceleration =
        pinocchio::getFrameClassicalAcceleration(model, data, static_cast<pinocchio::FrameIndex>(contact.frame), LWA);
    const Eigen::Vector3d position = data.oMf[contact.frame].translation() - contact.radius * normal;
    Rows3 point_jacobian = jacobian.topRows<3>();
    Eigen::Vector3d point_drift = acceleration.linear();
    if (contact.radius != 0.0) {  // the touching point of the sphere: v_c + omega x (-r n)
      const Eigen::Matrix3d arm = contact.radius * pinocchio::skew(normal);
      point_jacobian = point_jacobian + arm * jacobian.bottomRows<3>();
      point_drift = point_drift + arm * acceleration.angular();
    }
    if (carried) {  // relative to the plane's material point at p: w = v_p - v_b(p), a_p - a_b(p) - 2 omega_b x w
      const Jacobian6 body = frame_jacobian(model, data, contact.plane_frame);
      const pinocchio::Motion body_acceleration = pinocchio::getFrameClassicalAcceleration(
          model, data, static_cast<pinocchio::FrameIndex>(contact.plane_frame), LWA);
      const Eigen::Vector3d arm = position - plane.translation();
      const Eigen::Vector3d omega = body.bottomRows<3>() * v;
      const Rows3 carried_jacobian = body.topRows<3>() - pinocchio::skew(arm) * body.bottomRows<3>();
      point_jacobian = point_jacobian - carried_jacobian;
      const Eigen::Vector3d w = point_jacobian * v;
      const Eigen::Matrix3d spin = pinocchio::skew(omega);
      const Eigen::Vector3d carried_drift =
          body_acceleration.linear() + pinocchio::skew(body_acceleration.angular()) * arm + spin * (spin * arm);
      point_drift = point_drift - carried_drift - (2.0 * spin) * w;
    }
    const Eigen::Vector3d local = carried ? Eigen::Vector3d(plane.actInv(position)) : position;
    rows.positions.row(i) = position.transpose();
    rows.local.row(i) = local.transpose();
    rows.jacobian.middleRows<3>(3 * i) = basis * point_jacobian;
    rows.velocities.row(i) = (rows.jacobian.middleRows<3>(3 * i) * v).transpose();
    rows.drift.segment<3>(3 * i) = basis * point_drift;
    rows.bases.middleRows<3>(3 * i) = basis;
    rows.gaps(i) = contact.basis.row(0).dot(local - contact.origin);
  }
  return rows;
}

}  // namespace pinstab
