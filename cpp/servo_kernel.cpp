#include "servo_kernel.hpp"

#include <cmath>

#include <Eigen/QR>
#include <Eigen/SVD>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>

namespace pinstab {

ServoKernel::ServoKernel(const pinocchio::Model& model, Eigen::MatrixXd rows, Eigen::MatrixXd position_rows,
                         Eigen::MatrixXd actuation, VectorXd lower, VectorXd upper, std::vector<Target> targets, double kp, double kd,
                         double rank_tolerance)
    : model_(model),
      data_(model_),
      rows_(std::move(rows)),
      position_rows_(std::move(position_rows)),
      actuation_(std::move(actuation)),
      lower_(std::move(lower)),
      upper_(std::move(upper)),
      controls_(VectorXd::Zero(actuation_.cols())),
      targets_(std::move(targets)),
      kp_(kp),
      kd_(kd),
      rank_tolerance_(rank_tolerance),
      limited_(lower_.array().isFinite().any() || upper_.array().isFinite().any()) {}

bool ServoKernel::acceleration(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) {
  pinocchio::crba(model_, data_, q);
  data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose().triangularView<Eigen::StrictlyLower>();
  pinocchio::nonLinearEffects(model_, data_, q, v);
  mass_.compute(data_.M);
  free_ = mass_.solve(tau - data_.nle);  // a0
  moved_ = mass_.solve(actuation_);      // M^-1 B
  decoupling_.noalias() = rows_ * moved_;
  const int p = static_cast<int>(rows_.rows()), k = static_cast<int>(actuation_.cols());
  demand_.resize(p);
  for (int i = 0; i < p; ++i) {
    double value, rate, curvature;
    targets_[i].evaluate(t, value, rate, curvature);
    demand_(i) = curvature - kd_ * (rows_.row(i).dot(v) - rate) - kp_ * (position_rows_.row(i).dot(q) - value);
  }
  demand_.noalias() -= rows_ * free_;
  double sign = 0.0;
  if (p == 1) {  // (k >= 1: an actuation has a control)
    const double norm = decoupling_.row(0).norm();
    if (!(norm > rank_tolerance_ * std::max(norm, 1.0))) return false;
    controls_ = decoupling_.row(0).transpose() * (demand_(0) / decoupling_.row(0).squaredNorm());
    sign = decoupling_(0, 0) > 0.0 ? 1.0 : (decoupling_(0, 0) < 0.0 ? -1.0 : 0.0);
  } else {
    if (p > k) return false;  // more prescribed rows than controls: rank < p, the general solve says so
    const VectorXd singular = decoupling_.jacobiSvd().singularValues();
    if (!(singular(p - 1) > rank_tolerance_ * std::max(singular(0), 1.0))) return false;
    controls_ = decoupling_.completeOrthogonalDecomposition().solve(demand_);
    if (p == k) {
      const double det = decoupling_.determinant();
      sign = det > 0.0 ? 1.0 : (det < 0.0 ? -1.0 : 0.0);
    }
  }
  if (p == k) {
    if (last_sign_ && last_sign_->second != sign) return false;
    last_sign_ = std::make_pair(t, sign);
  }
  if (limited_ && ((controls_.array() < lower_.array()).any() || (controls_.array() > upper_.array()).any())) {
    return false;
  }
  a = free_;
  a.noalias() += moved_ * controls_;
  return a.allFinite();
}

}  // namespace pinstab
