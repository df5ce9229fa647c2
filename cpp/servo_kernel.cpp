#include "servo_kernel.hpp"

#include "rank_floor.hpp"
#include "stabilization.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/QR>
#include <Eigen/SVD>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>

namespace pinstab {

Realizability realizability(const Eigen::MatrixXd& decoupling, const Eigen::MatrixXd& rows, const Eigen::MatrixXd& moved,
                            double rank_tolerance, std::optional<double> last_sign) {
  const Eigen::Index p = decoupling.rows(), k = decoupling.cols();
  Realizability judged;
  judged.unit.resize(p, k);
  const VectorXd columns = moved.colwise().norm().transpose();
  for (Eigen::Index i = 0; i < p; ++i) {
    const double size = rows.row(i).norm();
    for (Eigen::Index j = 0; j < k; ++j) {
      // divided in two steps: |S_i| |N b_j| may overflow where the cosine does not
      judged.unit(i, j) = size > 0.0 && columns(j) > 0.0 ? decoupling(i, j) / size / columns(j) : 0.0;
    }
  }
  if (p == 0) return judged;
  const VectorXd singular = p == 1 ? VectorXd::Constant(1, judged.unit.row(0).norm())
                                   : VectorXd(judged.unit.jacobiSvd().singularValues());
  const double floor = rank_floor(singular, rank_tolerance);
  judged.rank = static_cast<int>((singular.array() > floor).count());
  if (p == k) {
    const double det = p == 1 ? judged.unit(0, 0) : judged.unit.determinant();
    judged.sign = det > 0.0 ? 1.0 : (det < 0.0 ? -1.0 : 0.0);
    judged.crossed = judged.rank == p && last_sign && *last_sign != judged.sign;
  }
  judged.usable = judged.rank == p && !judged.crossed;
  return judged;
}

bool controls_within(const VectorXd& controls, const VectorXd& lower, const VectorXd& upper) {
  return (controls.array() >= lower.array() && controls.array() <= upper.array()).all();
}

VectorXd least_norm(const Eigen::MatrixXd& decoupling, const VectorXd& demand) {
  if (decoupling.rows() == 1) {  // D^T d / |D|^2, what the QR gives, without its work
    return decoupling.row(0).transpose() * (demand(0) / decoupling.row(0).squaredNorm());
  }
  // D^T = Q [R; 0]: u = Q [R^-T demand; 0]
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(decoupling.transpose());
  const Eigen::Index p = decoupling.rows();
  VectorXd reduced = VectorXd::Zero(decoupling.cols());
  reduced.head(p) = qr.matrixQR().topLeftCorner(p, p).triangularView<Eigen::Upper>().transpose().solve(demand);
  return qr.householderQ() * reduced;
}

void ServoParts::compute(const Eigen::LLT<Eigen::MatrixXd>& mass, const VectorXd& force, const Eigen::MatrixXd& real,
                         const Eigen::MatrixXd& prescribed, const Eigen::MatrixXd& actuation, const VectorXd& real_rhs,
                         const VectorXd& prescribed_rhs) {
  base = mass.solve(force);        // M^-1 f
  moved = mass.solve(actuation);   // M^-1 B
  const Eigen::Index r = real.rows(), nv = force.size();
  spread.resize(nv, r);
  reach.resize(r, actuation.cols());
  base_multipliers.resize(r);
  if (r > 0) {
    spread = mass.solve(real.transpose());
    delassus.compute(real * spread, PSEUDO_INVERSE_CUTOFF);  // not finite: NaN, which the callers refuse
    reach.noalias() = spread.transpose() * actuation;
    base_multipliers = delassus.apply(VectorXd(real_rhs - real * base));
    base.noalias() += spread * base_multipliers;
    moved.noalias() -= spread * delassus.apply(reach);
  }
  decoupling.noalias() = prescribed * moved;
  demand = prescribed_rhs;
  demand.noalias() -= prescribed * base;
}

void ServoParts::finish(const VectorXd& controls, VectorXd& a, VectorXd& multipliers) const {
  a = base;
  a.noalias() += moved * controls;
  multipliers = base_multipliers;
  if (reach.rows() > 0) multipliers -= delassus.apply(VectorXd(reach * controls));
}

ServoKernel::ServoKernel(const pinocchio::Model& model, Eigen::MatrixXd rows, Eigen::MatrixXd position_rows,
                         Eigen::MatrixXd actuation, VectorXd lower, VectorXd upper, std::vector<Target> targets, double kp, double kd,
                         double rank_tolerance)
    : model_(model),
      data_(light_data(model_)),
      rows_(std::move(rows)),
      position_rows_(std::move(position_rows)),
      actuation_(std::move(actuation)),
      no_rows_(0, model.nv),
      lower_(std::move(lower)),
      upper_(std::move(upper)),
      controls_(VectorXd::Zero(actuation_.cols())),
      targets_(std::move(targets)),
      kp_(kp),
      kd_(kd),
      rank_tolerance_(rank_tolerance) {}

bool ServoKernel::acceleration(int, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                               VectorXd& a) {
  pinocchio::crba(model_, data_, q);
  data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose().triangularView<Eigen::StrictlyLower>();
  pinocchio::nonLinearEffects(model_, data_, q, v);
  mass_.compute(data_.M);
  const int p = static_cast<int>(rows_.rows()), k = static_cast<int>(actuation_.cols());
  rhs_.resize(p);
  for (int i = 0; i < p; ++i) {
    double value, rate, curvature;
    targets_[i].evaluate(t, value, rate, curvature);
    // -gamma0 plus the term, as the core kernel's right-hand side (a relation's gamma0 is -c'')
    rhs_(i) = curvature + stabilization_law(kp_, kd_, rows_.row(i).dot(v) - rate, position_rows_.row(i).dot(q) - value);
  }
  parts_.compute(mass_, tau - data_.nle, no_rows_, rows_, actuation_, no_multipliers_, rhs_);
  if (p > k) return false;  // more prescribed rows than controls: rank < p, the general solve says so
  const std::optional<double> last = last_sign_ ? std::optional<double>(last_sign_->second) : std::nullopt;
  const Realizability judged = realizability(parts_.decoupling, rows_, parts_.moved, rank_tolerance_, last);
  if (!judged.usable) return false;
  if (p == k) last_sign_ = std::make_pair(t, judged.sign);
  controls_ = least_norm(parts_.decoupling, parts_.demand);
  if (!controls_within(controls_, lower_, upper_)) return false;
  parts_.finish(controls_, a, no_multipliers_);
  return a.allFinite();
}

}  // namespace pinstab
