#include "implicit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace pinstab {

namespace {

constexpr double RATE_DROP = 0.3;
// a rate of convergence above this gets a fresh Jacobian at the next step's start (on stiff-fourbar, esdirk4 at rtol
// 1e-8 over 10 s: 0.5 -> 271k iterations, 537 Jacobians; 0.1 -> 234k, 1120; 0.01 -> 177k, 6281 at 5 evaluations each)
constexpr double SLOW_RATE = 0.1;
constexpr int GLOBAL_ITERATIONS = 40;  // the globalized iteration's Jacobians per stage
constexpr int SHARE_ITERATIONS = 6;    // its Newton iterations per share of the step
constexpr double MIN_SHARE = 1.0 / 1024.0;  // its smallest advance of the share
// a stage after the first two starts from the Lagrange polynomial in c through Z(0) = 0 and the increments of the
// last PREDICTOR_STAGES stages, extrapolated to its node (on stiff-fourbar, esdirk4 at rtol 1e-9 over 10 s: 496k
// iterations from the linearized guess; 459k with 1 stage, 385k with 2, 425k with 3, 461k with 4; the error 9.5e-7 rad
// in each)
constexpr int PREDICTOR_STAGES = 2;

}  // namespace

ImplicitTrial::ImplicitTrial(const Pair& pair, int nv, const pinocchio::Model* group, const NewtonSettings& settings)
    : Trial(pair, nv, group), settings_(settings), increments_(pair.stages(), 2 * nv), scale_(2 * nv), z_(2 * nv),
      known_(2 * nv), residual_(2 * nv), dz_(2 * nv), rhs_(nv), qi_(nv), vi_(nv), ai_(nv), behind_(2 * nv),
      trial_(2 * nv) {}

bool ImplicitTrial::refresh(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t,
                            int i) {
  ++counts.jacobians;
  if (!kernel.jacobian(i, t, q, v, tau, dadq_, dadv_)) return false;
  jacobian_ = true;
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

void ImplicitTrial::linearized_guess(int i, double share, double shg, VectorXd& out) {
  if (shg != factored_) factor(shg);
  residual_ = slopes.row(i - 1).transpose();
  solve(shg);
  out = share * known_ + shg * dz_;
}

double ImplicitTrial::scaled_norm(const VectorXd& x) const {
  double norm = 0.0;
  for (int c = 0; c < 2 * nv_; ++c) {
    const double scaled = std::abs(x(c)) / scale_(c);
    norm = std::isnan(scaled) || std::isnan(norm) ? NAN : std::max(norm, scaled);
  }
  return norm;
}

bool ImplicitTrial::evaluate(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v,
                             double t_stage, double share, double hg, int i, const VectorXd& z) {
  qi_ = group_.integrate(q, z.head(nv_));
  vi_ = v + z.tail(nv_);
  ++evaluations;
  ++counts.iterations;
  ++failed_iterations;
  if (!kernel.acceleration(i, t_stage, qi_, vi_, tau, ai_)) return false;
  residual_ << group_.slope(q, qi_, vi_), ai_;
  residual_ = share * known_ + hg * residual_ - z;
  return true;
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
  if (i <= PREDICTOR_STAGES) {
    linearized_guess(i, 1.0, hg, z_);
  } else {  // later stages: the stage increments' polynomial through (0, 0) and the last two
    z_.setZero();
    const double c = pair_.nodes(i);
    for (int j = i - PREDICTOR_STAGES; j < i; ++j) {
      double weight = c / pair_.nodes(j);
      for (int m = i - PREDICTOR_STAGES; m < i; ++m) {
        if (m != j) weight *= (c - pair_.nodes(m)) / (pair_.nodes(j) - pair_.nodes(m));
      }
      z_ += weight * increments_.row(j).transpose();
    }
  }
  const double kappa = std::max(settings_.kappa, 10.0 * std::numeric_limits<double>::epsilon() / settings_.rtol);
  double eta = std::pow(std::max(eta_, std::numeric_limits<double>::epsilon()), 0.8), previous = 0.0, rate = 1.0;
  failed_iterations = 0;
  for (int since = 0; since < settings_.max_iterations; ++since) {
    if (!evaluate(kernel, tau, q, v, t_stage, 1.0, hg, i, z_)) return Solve::unusable;
    solve(hg);
    const double norm = scaled_norm(dz_);
    residual = norm;
    if (!std::isfinite(norm)) break;
    z_ += dz_;
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
      increments_.row(i) = z_.transpose();
      return Solve::converged;
    }
    if (hopeless) break;
    previous = norm;
  }
  const Solve solved = globalize(kernel, tau, q, v, t_stage, hg, kappa, i);
  slow_ = true;  // a fresh Jacobian at the next step's start
  return solved;
}

ImplicitTrial::Solve ImplicitTrial::globalize(Kernel& kernel, const VectorXd& tau, const VectorXd& q,
                                              const VectorXd& v, double t_stage, double hg, double kappa, int i) {
  // The stage of the step's share s: Z(s) = s S_i + s h g F(Z(s)), Z(0) = 0, followed from s = 0 to 1 (each share's
  // solution by Newton's iteration with a Jacobian at every iterate, from a linear extrapolation of the last two)
  double share = 0.0, last = 0.0, length = 1.0;
  z_.setZero();
  behind_.setZero();  // the solution at the share before the last
  for (int jacobians = 0; jacobians < GLOBAL_ITERATIONS;) {
    const double target = std::min(1.0, share + length), shg = target * hg;
    if (share == 0.0) {  // the linearized stage of the share: the stage's own guess at share 1
      linearized_guess(i, target, shg, trial_);
    } else {
      trial_ = z_ + ((target - share) / (share - last)) * (z_ - behind_);
    }
    Solve solved = Solve::unconverged;
    double previous = INFINITY;
    for (int k = 0; k < SHARE_ITERATIONS && jacobians < GLOBAL_ITERATIONS; ++k, ++jacobians) {
      if (!evaluate(kernel, tau, q, v, t_stage, target, shg, i, trial_)) return Solve::unusable;
      ++counts.globalized;
      if (!refresh(kernel, tau, qi_, vi_, t_stage, i)) return Solve::unusable;
      factor(shg);
      solve(shg);
      const double norm = scaled_norm(dz_);
      residual = norm;
      if (!(norm < previous)) break;  // not contracting (or NaN): a shorter share
      trial_ += dz_;
      if (norm <= kappa) {
        solved = Solve::converged;
        break;
      }
      previous = norm;
    }
    if (solved == Solve::converged) {
      if (target == 1.0) {
        z_ = trial_;
        eta_ = 1.0;
        slopes.row(i) = ((z_ - known_) / hg).transpose();
        increments_.row(i) = z_.transpose();
        return Solve::converged;
      }
      ++counts.continuation;
      behind_ = z_;
      last = share;
      z_ = trial_;
      share = target;
      length *= 2.0;
    } else {
      length *= 0.5;
      if (length < MIN_SHARE) return Solve::unconverged;  // the stage's solution turns back (a fold) before s = 1
    }
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
  for (int i = 1; i < stages; ++i) {
    const Solve solved = stage(kernel, tau, q, v, t, h, i);
    if (solved == Solve::unusable) return false;
    if (solved == Solve::unconverged) {
      failed_stage = i;
      ++counts.failures;
      unconverged = true;
      return false;
    }
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
       << " s, neither simplified nor globalized (a continuation in the stage's share, at most " << GLOBAL_ITERATIONS
       << " Jacobians): its last scaled increment was " << residual << " after "
       << failed_iterations << " evaluations; a smaller step solves it (--dt, or error control with --rtol)";
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
