#include "implicit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace pinstab {

namespace {

constexpr double RATE_DROP = 0.3;
constexpr int MAX_UPDATES = 8;  // Jacobians at a stage's iterate per stage (2 left stiff-fourbar's implicit-euler at
// dt = 10 ms with the spring-damper 2.3 times stiffer unsolved at t = 0.53 s; 8 solves it)
// a rate of convergence above this gets a fresh Jacobian at the next step's start (on stiff-fourbar, esdirk4 at rtol
// 1e-8 over 10 s: 0.5 -> 271k iterations, 537 Jacobians; 0.1 -> 234k, 1120; 0.01 -> 177k, 6281 at 5 evaluations each)
constexpr double SLOW_RATE = 0.1;

}  // namespace

ImplicitTrial::ImplicitTrial(const Pair& pair, int nv, const pinocchio::Model* group, const NewtonSettings& settings)
    : Trial(pair, nv, group), settings_(settings), scale_(2 * nv), z_(2 * nv), known_(2 * nv), residual_(2 * nv),
      dz_(2 * nv), rhs_(nv), qi_(nv), vi_(nv), ai_(nv) {}

bool ImplicitTrial::refresh(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t,
                            int i) {
  ++counts.jacobians;
  if (!kernel.jacobian(i, t, q, v, tau, dadq_, dadv_)) return false;
  jacobian_ = fresh_ = true;
  slow_ = false;
  factored_ = 0.0;
  return true;
}

void ImplicitTrial::solve(double hg) {
  rhs_ = residual_.tail(nv_) + hg * (dadq_ * residual_.head(nv_));
  dz_.tail(nv_) = lu_.solve(rhs_);
  dz_.head(nv_) = residual_.head(nv_) + hg * dz_.tail(nv_);
}

void ImplicitTrial::factor(double hg) {
  const Eigen::MatrixXd matrix = Eigen::MatrixXd::Identity(nv_, nv_) - hg * dadv_ - (hg * hg) * dadq_;
  lu_.compute(matrix);
  factored_ = hg;
  ++counts.factorizations;
}

ImplicitTrial::Solve ImplicitTrial::stage(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v,
                                          double t, double h, int i) {
  const double hg = h * pair_.coupling(i, i), t_stage = t + pair_.nodes(i) * h;
  known_.setZero();
  for (int j = 0; j < i; ++j) known_ += (h * pair_.coupling(i, j)) * slopes.row(j).transpose();
  if (!jacobian_ && !refresh(kernel, tau, q, v, t, i)) return Solve::unusable;
  if (hg != factored_) factor(hg);
  // the guess: the last stage's slope k carried through the linearized stage, Z = S_i + h g (I - h g J)^-1 k (a
  // linearly implicit Euler step; the explicit one, S_i + h g k, overshoots a stiff mode by h g |lambda|)
  residual_ = slopes.row(i - 1).transpose();
  solve(hg);
  z_ = known_ + hg * dz_;
  const double kappa = std::max(settings_.kappa, 10.0 * std::numeric_limits<double>::epsilon() / settings_.rtol);
  double eta = std::pow(std::max(eta_, std::numeric_limits<double>::epsilon()), 0.8), previous = 0.0, rate = 1.0;
  int updates = 0;
  failed_iterations = 0;
  for (int since = 0; since < settings_.max_iterations; ++since) {  // iterations since the Jacobian's last update
    qi_ = group_.integrate(q, z_.head(nv_));
    vi_ = v + z_.tail(nv_);
    ++evaluations;
    ++counts.iterations;
    ++failed_iterations;
    if (!kernel.acceleration(i, t_stage, qi_, vi_, tau, ai_)) return Solve::unusable;
    residual_ << group_.slope(q, qi_, vi_), ai_;
    residual_ = known_ + hg * residual_ - z_;
    solve(hg);
    z_ += dz_;
    double norm = 0.0;
    for (int c = 0; c < 2 * nv_; ++c) {
      const double scaled = std::abs(dz_(c)) / scale_(c);
      norm = std::isnan(scaled) || std::isnan(norm) ? NAN : std::max(norm, scaled);
    }
    residual = norm;
    if (!std::isfinite(norm)) return Solve::unconverged;
    bool hopeless = false;
    if (since > 0) {
      const double theta = norm / previous;
      if (theta > SLOW_RATE) slow_ = true;
      // the rate the stop trusts falls by at most RATE_DROP per iteration (SUNDIALS' crate): a first increment far
      // larger than the next (a poor guess) does not pass for fast convergence
      rate = std::max(RATE_DROP * rate, theta);
      eta = rate / (1.0 - rate);
      // diverging, or at this rate the iterations left cannot reach the tolerance (Hairer and Wanner's test)
      hopeless = theta >= 1.0 ||
                 std::pow(theta, settings_.max_iterations - 1 - since) / (1.0 - theta) * norm > kappa;
    }
    const bool trusted = since == 0 || rate < 1.0;  // the first iteration: the last stage's estimate
    if (norm == 0.0 || (trusted && eta * norm <= kappa)) {
      eta_ = eta;
      slopes.row(i) = ((z_ - known_) / hg).transpose();
      return Solve::converged;
    }
    if (hopeless) {  // a Jacobian at the iterate (its own Newton step), at most MAX_UPDATES times per stage
      if (updates == MAX_UPDATES) return Solve::unconverged;
      ++updates;
      if (!refresh(kernel, tau, group_.integrate(q, z_.head(nv_)), v + z_.tail(nv_), t_stage, i)) {
        return Solve::unusable;
      }
      factor(hg);
      since = -1, rate = 1.0, eta = 1.0;
      continue;
    }
    previous = norm;
  }
  return Solve::unconverged;
}

bool ImplicitTrial::take(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, const VectorXd& a,
                         double t, double h, bool with_end) {
  const int stages = pair_.stages();
  has_end = unconverged = false;
  slopes.row(0) << v.transpose(), a.transpose();
  scale_ << magnitude(group_, q), v.cwiseAbs();
  scale_ = settings_.atol + settings_.rtol * scale_.array();
  if (slow_) jacobian_ = false;  // the last iteration converged slowly: a fresh Jacobian at this step's start
  fresh_ = false;
  while (true) {
    Solve solved = Solve::converged;
    for (int i = 1; i < stages && solved == Solve::converged; ++i) {
      solved = stage(kernel, tau, q, v, t, h, i);
      if (solved != Solve::converged) failed_stage = i;
    }
    if (solved == Solve::unusable) return false;
    if (solved == Solve::converged) break;
    ++counts.failures;
    if (fresh_) {
      unconverged = true;
      return false;
    }
    jacobian_ = false;  // retry the step with a fresh Jacobian
  }
  if (pair_.stiffly_accurate()) {
    increment_ = z_;  // the last stage's increment: the step ends on it
  } else {
    increment_.setZero();
    for (int j = 0; j < stages; ++j) increment_ += (h * pair_.weights(j)) * slopes.row(j).transpose();
  }
  q_new = group_.integrate(q, increment_.head(nv_));
  v_new = v + increment_.tail(nv_);
  if (pair_.stiffly_accurate()) {
    end = slopes.row(stages - 1).transpose();
    has_end = true;
  } else if (with_end) {
    ++evaluations;
    if (!kernel.acceleration(0, t + h, q_new, v_new, tau, a_)) return false;
    end << group_.slope(q, q_new, v_new), a_;
    has_end = true;
  }
  return true;
}

std::string ImplicitTrial::failure(double t, double h) const {
  std::ostringstream text;
  text << "Newton's iteration did not solve stage " << failed_stage << " of the step of " << h << " s from t = " << t
       << " s with a fresh Jacobian: its scaled increment was " << residual << " after " << failed_iterations
       << " iterations";
  return text.str();
}

std::unique_ptr<Trial> make_trial(const Pair& pair, int nv, const pinocchio::Model* group,
                                  const NewtonSettings& settings) {
  if (pair.implicit()) return std::make_unique<ImplicitTrial>(pair, nv, group, settings);
  return std::make_unique<Trial>(pair, nv, group);
}

void check_tableau(const Pair& pair, const char* where) {
  const Eigen::Index s = pair.nodes.size();
  if (s < 1 || pair.coupling.rows() != s || pair.coupling.cols() != s || pair.weights.size() != s) {
    throw std::invalid_argument(std::string(where) + ": nodes (s), coupling (s x s) and weights (s) of one tableau");
  }
  for (Eigen::Index i = 0; i < s; ++i) {
    for (Eigen::Index j = i + 1; j < s; ++j) {
      if (pair.coupling(i, j) != 0.0) throw std::invalid_argument(std::string(where) + ": coupling above its diagonal");
    }
  }
  if (pair.implicit() && (pair.coupling.row(0).array() != 0.0).any()) {
    throw std::invalid_argument(std::string(where) + ": an implicit tableau's first stage must be explicit (a_1j = 0)");
  }
}

}  // namespace pinstab
