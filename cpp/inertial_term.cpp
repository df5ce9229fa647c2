#include "inertial_term.hpp"

#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>

#include "kkt_solve.hpp"

namespace pinstab {
namespace {

// D = G M^-1 G^T
Eigen::MatrixXd delassus_of(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian) {
  return jacobian * Eigen::LLT<Eigen::MatrixXd>(mass).solve(jacobian.transpose());
}

}  // namespace

std::pair<Eigen::MatrixXd, Eigen::MatrixXd> inertial_matrices(const InertialGains& gains, const Eigen::MatrixXd& mass,
                                                              const Eigen::MatrixXd& jacobian,
                                                              const Eigen::MatrixXd& mass_ahead,
                                                              const Eigen::MatrixXd& jacobian_ahead) {
  const Eigen::MatrixXd delassus = delassus_of(mass, jacobian);
  const Eigen::MatrixXd rate = (delassus_of(mass_ahead, jacobian_ahead) - delassus) / gains.rate_step;
  DelassusPseudoInverse inertia;
  inertia.compute(delassus, gains.cutoff);
  // rate D^+ = (D^+ rate^T)^T, D^+ being symmetric
  return {delassus * gains.stiffness,
          delassus * gains.damping - inertia.apply(Eigen::MatrixXd(rate.transpose())).transpose()};
}

InertialPass::InertialPass(const pinocchio::Model& model, InertialGains gains)
    : gains_(std::move(gains)), ahead_(light_data(model)) {}

VectorXd InertialPass::term(const pinocchio::Model& model, const std::vector<RowBlock>& blocks,
                            const std::vector<int>& offsets, double t, const VectorXd& q, const VectorXd& v,
                            const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, const VectorXd& phi,
                            const VectorXd& rate) {
  VectorXd q_ahead(q.size());
  pinocchio::integrate(model, q, VectorXd(gains_.rate_step * v), q_ahead);
  pinocchio::computeJointJacobians(model, ahead_, q_ahead);
  pinocchio::updateFramePlacements(model, ahead_);
  pinocchio::crba(model, ahead_, q_ahead);
  ahead_.M.triangularView<Eigen::StrictlyLower>() = ahead_.M.transpose().triangularView<Eigen::StrictlyLower>();
  jacobian_ahead_.setZero(jacobian.rows(), jacobian.cols());
  time_term_.setZero(jacobian.rows());
  for (size_t k = 0; k < blocks.size(); ++k) {
    const int rows = blocks[k].rows();
    block_jacobian(model, ahead_, blocks[k], t, jacobian_ahead_.middleRows(offsets[k], rows),
                   time_term_.segment(offsets[k], rows));
  }
  const auto [stiffness, damping] = inertial_matrices(gains_, mass, jacobian, ahead_.M, jacobian_ahead_);
  return -(stiffness * phi) - damping * rate;
}

}  // namespace pinstab
