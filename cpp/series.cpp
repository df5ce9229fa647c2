// The drift and energy series of a run of closures (see series.hpp).
#include "series.hpp"

#include <cmath>
#include <limits>

#include <pinocchio/algorithm/energy.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

namespace pinstab {

namespace {

// The largest |x_i|; NaN when some x_i is NaN (numpy's max), 0 for none.
double largest(const VectorXd& x) {
  double value = 0.0;
  for (const double entry : x) {
    if (std::isnan(entry)) return entry;
    value = std::max(value, std::abs(entry));
  }
  return value;
}

}  // namespace

std::tuple<VectorXd, VectorXd, VectorXd> closure_series(const pinocchio::Model& model, pinocchio::Data& data,
                                                        const ClosurePoints& points, const RowMatrix& qs,
                                                        const RowMatrix& vs) {
  const long n = qs.rows();
  const int closures = static_cast<int>(points.joints_a.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  VectorXd position = VectorXd::Constant(n, nan), velocity = VectorXd::Constant(n, nan),
           energy = VectorXd::Constant(n, nan);
  Eigen::Matrix3Xd difference(3, closures), rate(3, closures);
  VectorXd phi(points.owner.size()), g(points.owner.size());
  for (long k = 0; k < n; ++k) {
    if (!qs.row(k).allFinite() || !vs.row(k).allFinite()) continue;
    pinocchio::forwardKinematics(model, data, qs.row(k).transpose(), vs.row(k).transpose());
    for (int c = 0; c < closures; ++c) {
      // each side's point and its velocity in world axes: oMi p (as the frame placement oMi * placement that
      // Pinocchio's updateFramePlacements computes) and the joint's world-frame twist at that point
      Eigen::Vector3d point[2], speed[2];
      const int joints[2] = {points.joints_a(c), points.joints_b(c)};
      for (int side = 0; side < 2; ++side) {
        const pinocchio::SE3& placement = data.oMi[joints[side]];
        const Eigen::Vector3d local = (side == 0 ? points.local_a : points.local_b).row(c).transpose();
        point[side] = placement.translation() + placement.rotation() * local;
        const pinocchio::Motion twist = placement.act(data.v[joints[side]]);
        speed[side] = twist.linear() + twist.angular().cross(point[side]);
      }
      difference.col(c) = point[0] - point[1];
      rate.col(c) = speed[0] - speed[1];
    }
    for (int r = 0; r < points.owner.size(); ++r) {
      phi(r) = points.selection.row(r).dot(difference.col(points.owner(r)).transpose());
      g(r) = points.selection.row(r).dot(rate.col(points.owner(r)).transpose());
    }
    position(k) = largest(phi);
    velocity(k) = largest(g);
    // after the pass at (q, v): Pinocchio's kinetic and potential energy (the same sums its calls at (q, v) make)
    energy(k) = pinocchio::computeKineticEnergy(model, data) + pinocchio::computePotentialEnergy(model, data);
  }
  return {position, velocity, energy};
}

}  // namespace pinstab
