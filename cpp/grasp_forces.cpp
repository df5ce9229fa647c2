#include "grasp_forces.hpp"

#include "rank_floor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>

namespace pinstab {

bool add_hold_torques(const pinocchio::Model& model, const pinocchio::Data& data, const HoldSpec& hold,
                      const Eigen::MatrixXd& jacobian, const VectorXd& q, const VectorXd& v,
                      Eigen::Ref<VectorXd> force) {
  const int count = static_cast<int>(hold.rows.size());
  Eigen::MatrixXd carrier(hold.object_columns.size(), count);  // A_object^T
  VectorXd load(hold.object_columns.size());
  for (int i = 0; i < hold.object_columns.size(); ++i) {
    for (int k = 0; k < count; ++k) carrier(i, k) = jacobian(hold.rows(k), hold.object_columns(i));
    load(i) = data.g(hold.object_columns(i));
  }
  VectorXd forces;
  if (!closest_solution(carrier, load, hold.pressing, hold.rank, hold.condition, forces)) return false;
  if (!cones_hold(hold.cones, hold.cap, hold.feasibility, forces)) return false;
  VectorXd deviation(model.nv);
  pinocchio::difference(model, hold.q_start, q, deviation);
  add_hold_balance(jacobian, hold.rows, hold.hand_columns, data.g, forces, deviation, v, hold.stiffness, hold.damping,
                   force);
  return true;
}

void add_hold_balance(const Eigen::MatrixXd& jacobian, const VectorXi& rows, const VectorXi& hand_columns,
                      const VectorXd& gravity, const VectorXd& forces, const VectorXd& deviation, const VectorXd& v,
                      double stiffness, double damping, Eigen::Ref<VectorXd> force) {
  for (int i = 0; i < hand_columns.size(); ++i) {
    const int column = hand_columns(i);
    double pushed = 0.0;
    for (int k = 0; k < rows.size(); ++k) pushed += jacobian(rows(k), column) * forces(k);
    force(column) += gravity(column) - pushed - stiffness * deviation(column) - damping * v(column);
  }
}

void add_wrench(const pinocchio::Model& model, pinocchio::Data& data, const WrenchSpec& wrench,
                Eigen::Ref<VectorXd> force) {
  Eigen::Matrix<double, 6, Eigen::Dynamic> jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, model.nv);
  pinocchio::getFrameJacobian(model, data, wrench.frame, pinocchio::LOCAL_WORLD_ALIGNED, jacobian);
  force.noalias() += jacobian.transpose() * wrench.wrench;
}

bool closest_solution(const Eigen::MatrixXd& matrix, const VectorXd& rhs, const VectorXd& target, double rank,
                      double condition, VectorXd& x) {
  const VectorXd residual = rhs - matrix * target;
  if (matrix.rows() <= matrix.cols()) {
    const Eigen::LLT<Eigen::MatrixXd> gram(matrix * matrix.transpose());
    if (gram.info() == Eigen::Success && gram.rcond() * condition * condition >= 1.0) {
      x = target + matrix.transpose() * gram.solve(residual);
      return x.allFinite();
    }
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(matrix, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const VectorXd& singular = svd.singularValues();
  const double floor = rank_floor(singular, rank);
  x = target;
  for (int k = 0; k < singular.size() && singular(k) > floor; ++k) {
    x += svd.matrixV().col(k) * (svd.matrixU().col(k).dot(residual) / singular(k));
  }
  return x.allFinite();
}

bool cones_hold(const std::vector<ConeSpec>& cones, double cap, double feasibility, const VectorXd& forces) {
  if (!forces.allFinite()) return false;  // a force that is not a number holds nothing
  const double slack = -feasibility * (1.0 + (forces.size() ? forces.cwiseAbs().maxCoeff() : 0.0));
  for (const ConeSpec& cone : cones) {
    const double normal = forces(cone.normal);
    if (normal < slack) return false;
    if (cone.tangent1 >= 0 && cone.mu * normal - std::hypot(forces(cone.tangent1), forces(cone.tangent2)) < slack) {
      return false;
    }
    if (cone.spin >= 0 && cone.torsion * normal - std::abs(forces(cone.spin)) < slack) return false;
    if (std::isfinite(cap) && normal > cap * (1.0 + 1e-9)) return false;
  }
  return true;
}

Eigen::Vector3d contact_margins(ContactModel model, double mu, double torsion,
                                const Eigen::Matrix<double, 6, 1>& wrench) {
  const double inf = std::numeric_limits<double>::infinity();
  if (model == ContactModel::rigid) return Eigen::Vector3d::Constant(inf);
  const bool friction = model == ContactModel::point_friction || model == ContactModel::soft_finger;
  return {wrench(2), friction ? mu * wrench(2) - std::hypot(wrench(0), wrench(1)) : inf,
          model == ContactModel::soft_finger ? torsion * wrench(2) - std::abs(wrench(5)) : inf};
}

bool contact_holds(ContactModel model, double mu, double torsion, const Eigen::Matrix<double, 6, 1>& wrench,
                   double slack) {
  const double floor = -slack * (1.0 + wrench.cwiseAbs().maxCoeff());
  return (contact_margins(model, mu, torsion, wrench).array() >= floor).all();
}

}  // namespace pinstab
