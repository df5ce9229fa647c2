#include "adaptive.hpp"
#include "step_loop.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace pinstab {

bool Pair::needs_end() const {
  return estimators.cols() > stages() && (estimators.col(stages()).array() != 0.0).any();
}

bool Pair::implicit() const { return (coupling.diagonal().array() != 0.0).any(); }

bool Pair::stiffly_accurate() const { return (coupling.row(stages() - 1).transpose().array() == weights.array()).all(); }

double next_step(const Control& control, double h, double error, double proposed, double previous, bool rejected) {
  const bool limited = h < proposed * (1.0 - 1e-12);  // shortened for a passage or a chunk's end
  double optimal = INFINITY;
  if (error > 0.0) {
    optimal = h * control.safety * std::pow(error, control.pi_alpha * control.exponent);
    optimal *= std::pow(std::max(previous, 1e-4), -control.pi_beta * control.exponent);
  }
  const double growth = rejected ? 1.0 : control.max_factor;
  return std::min(std::max(optimal, control.min_factor * h), (limited ? proposed : h) * growth);
}

double shrink(const Control& control, double h, double error) {
  if (!std::isfinite(error)) return h * control.min_factor;
  return h * std::max(control.min_factor, control.safety * std::pow(error, control.exponent));
}

void hermite_coefficients(const Eigen::Ref<const Eigen::MatrixXd>& inverse, const Eigen::Ref<const RowMatrix>& ends,
                          Eigen::Ref<RowMatrix> coefficients) {
  for (Eigen::Index k = 0; k < inverse.rows(); ++k) {
    coefficients.row(k).setZero();
    for (Eigen::Index j = 0; j < inverse.cols(); ++j) coefficients.row(k) += inverse(k, j) * ends.row(j);
  }
}

void hermite_state(const Eigen::Ref<const RowMatrix>& coefficients, double u, double h, Eigen::Ref<VectorXd> increment,
                   Eigen::Ref<VectorXd> rate) {
  increment.setZero();
  rate.setZero();
  double below = 0.0;  // u^(k-1)
  for (Eigen::Index k = 0; k < coefficients.rows(); ++k) {
    const double power = std::pow(u, static_cast<double>(k));
    increment += power * coefficients.row(k).transpose();
    rate += (static_cast<double>(k) * below) * coefficients.row(k).transpose();
    below = power;
  }
  if (h != 0.0) rate /= h;
}

Trial::Trial(const Pair& pair, int nv, const pinocchio::Model* group)
    : q_new(nv), v_new(nv), end(2 * nv), slopes(pair.stages(), 2 * nv), pair_(pair), nv_(nv), group_(group),
      increment_(2 * nv), q_(nv), v_(nv), a_(nv) {}

void Trial::use_group(const pinocchio::Model* group) {
  if (group != group_.model) group_ = Group(group);
}

bool Trial::take(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, const VectorXd& a,
                 double t, double h, bool with_end) {
  const int stages = pair_.stages();
  has_end = false;
  slopes.row(0) << v.transpose(), a.transpose();
  for (int i = 1; i < stages; ++i) {
    increment_.setZero();
    for (int j = 0; j < i; ++j) increment_ += (h * pair_.coupling(i, j)) * slopes.row(j).transpose();
    q_ = group_.integrate(q, increment_.head(nv_));
    v_ = v + increment_.tail(nv_);
    ++evaluations;
    if (!kernel.acceleration(i, t + pair_.nodes(i) * h, q_, v_, tau, a_)) return false;
    slopes.row(i) << group_.slope(q, q_, v_).transpose(), a_.transpose();
  }
  increment_.setZero();
  for (int j = 0; j < stages; ++j) increment_ += (h * pair_.weights(j)) * slopes.row(j).transpose();
  q_new = group_.integrate(q, increment_.head(nv_));
  v_new = v + increment_.tail(nv_);
  if (with_end) {
    ++evaluations;
    if (!kernel.acceleration(0, t + h, q_new, v_new, tau, a_)) return false;
    end << group_.slope(q, q_new, v_new), a_;
    has_end = true;
  }
  return true;
}

double Trial::error(const Control& control, const VectorXd& size, const VectorXd& size_new, double h) const {
  const int stages = pair_.stages(), count = static_cast<int>(pair_.estimators.rows());
  double largest[2] = {0.0, 0.0};
  VectorXd estimate(2 * nv_);
  for (int e = 0; e < count; ++e) {
    estimate.setZero();
    for (int j = 0; j < stages; ++j) estimate += pair_.estimators(e, j) * slopes.row(j).transpose();
    if (pair_.needs_end()) estimate += pair_.estimators(e, stages) * end;
    double worst = 0.0;
    for (int i = 0; i < 2 * nv_; ++i) {
      const double scaled = std::abs(estimate(i) / (control.atol + control.rtol * std::max(size(i), size_new(i))));
      if (std::isnan(scaled) || std::isnan(worst)) {
        worst = NAN;
      } else {
        worst = std::max(worst, scaled);
      }
    }
    largest[e] = worst;
  }
  if (count == 1) return std::abs(h) * largest[0];
  const double fifth = largest[0], third = largest[1];
  if (fifth == 0.0 && third == 0.0) return 0.0;
  return std::abs(h) * fifth * fifth / std::sqrt(fifth * fifth + control.estimator_mix * third * third);
}

void Segment::fit(Group& group, const Hermite& hermite, double start, const VectorXd& q_start, const VectorXd& v0,
                  const VectorXd* a0, double t1, const VectorXd& q1, const VectorXd& v1, const VectorXd* a1) {
  t0 = start, h = t1 - start, q0 = q_start;
  const Eigen::Index nv = v0.size();
  const bool accelerations = a0 != nullptr && a1 != nullptr;
  const Eigen::MatrixXd& inverse = !accelerations ? hermite.cubic : group.flat ? hermite.quintic : hermite.quartic;
  RowMatrix ends(inverse.cols(), nv);
  Eigen::Index row = 0;
  ends.row(row++).setZero();
  ends.row(row++) = (h * v0).transpose();
  if (accelerations) ends.row(row++) = ((h * h) * *a0).transpose();
  if (group.euclidean) {
    ends.row(row++) = (q1 - q0).transpose();
  } else {
    VectorXd increment(nv);
    pinocchio::difference(*group.model, q0, q1, increment);
    ends.row(row++) = increment.transpose();
  }
  ends.row(row++) = (h * group.slope(q0, q1, v1)).transpose();
  if (row < ends.rows()) ends.row(row) = ((h * h) * *a1).transpose();
  coefficients.resize(inverse.rows(), nv);
  hermite_coefficients(inverse, ends, coefficients);
}

void Segment::state(Group& group, double t, VectorXd& q, VectorXd& v) const {
  VectorXd increment(coefficients.cols());
  v.resize(coefficients.cols());
  hermite_state(coefficients, h != 0.0 ? (t - t0) / h : 0.0, h, increment, v);
  if (group.euclidean) {
    q = q0 + increment;
    return;
  }
  q = group.integrate(q0, increment);
  if (group.flat) return;
  pinocchio::dDifference(*group.model, q0, q, group.carry, pinocchio::ARG1);  // v = dDifference(q0, q) v(q)
  v = group.carry.partialPivLu().solve(VectorXd(v));
}

VectorXd magnitude(const Group& group, const VectorXd& q) {
  if (group.euclidean) return q.cwiseAbs();
  VectorXd increment(group.model->nv);
  pinocchio::difference(*group.model, pinocchio::neutral(*group.model), q, increment);
  return increment.cwiseAbs();
}

int advance_tableau(Kernel& kernel, Trial& trial, const VectorXd& q0, const VectorXd& v0, const VectorXd& tau,
                    double dt, long start, int steps, RowMatrix& qs, RowMatrix& vs, Correction* correction) {
  VectorXd a(kernel.nv());
  auto take = [&](double t, VectorXd& q, VectorXd& v) {
    if (!kernel.acceleration(0, t, q, v, tau, a) || !trial.take(kernel, tau, q, v, a, t, dt, false)) return false;
    q = trial.q_new;
    v = trial.v_new;
    return true;
  };
  return fixed_steps(take, q0, v0, dt, start, steps, qs, vs, correction);
}

Outcome attempt(Trial& trial, Kernel& kernel, const Pair& pair, const Control& control, const VectorXd& tau,
                const VectorXd& q, const VectorXd& v, const VectorXd& a, const VectorXd& size, double t, double& h,
                double& error, long& rejected) {
  const auto* own = dynamic_cast<const Refusing*>(&kernel);
  const int nv = kernel.nv();
  VectorXd size_new(2 * nv);
  rejected = 0;
  while (true) {
    if (trial.take(kernel, tau, q, v, a, t, h, pair.needs_end())) {
      size_new << magnitude(trial.group(), trial.q_new), trial.v_new.cwiseAbs();
      error = trial.error(control, size, size_new, h);
      if (error <= 1.0) return Outcome::accepted;
      if (!std::isfinite(error) && own == nullptr) return Outcome::handed_back;  // Python's evaluation says why
    } else if (trial.unconverged) {
      error = INFINITY;  // an implicit stage not solved: a shorter step
    } else {
      if (own == nullptr) return Outcome::handed_back;  // not to be used: the Python loop's evaluation takes it
      if (!own->refused() || shrink(control, h, INFINITY) < control.min_step * std::max(1.0, t)) {
        return Outcome::raised;
      }
      error = INFINITY;  // a state refused by a stage: a shorter step
    }
    ++rejected;
    h = shrink(control, h, error);
    if (h < control.min_step * std::max(1.0, t)) return own == nullptr ? Outcome::handed_back : Outcome::too_short;
  }
}

namespace {

long floor_index(double x) { return static_cast<long>(std::floor(x)); }

}  // namespace

int adaptive_advance(Kernel& kernel, Trial& trial, const Pair& pair, const Control& control, const Grid& grid,
                     const Stops& stops, const VectorXd& tau, ControlState& state, long& first, RowMatrix& qs,
                     RowMatrix& vs) {
  const int nv = kernel.nv();
  const bool own = dynamic_cast<const Refusing*>(&kernel) != nullptr;
  Group group(kernel.group());
  Segment segment;
  VectorXd a_new(nv), q_sample, v_sample, size(2 * nv);
  first = floor_index(state.t / grid.dt + grid.slack) + 1;
  int count = 0;
  state.outcome = Outcome::handed_back;
  while (state.t < stops.t_stop - grid.slack * grid.dt && !(state.t >= stops.due)) {
    const double t = state.t;
    const double proposal = stops.t_stop - t < state.step_size * (1 + grid.slack) ? stops.t_stop - t : state.step_size;
    if (t < stops.crossing && stops.crossing < t + stops.horizon * proposal) break;  // the passage watch plans
    size << magnitude(group, state.q), state.v.cwiseAbs();
    double h = proposal, error = 0.0;
    long rejected = 0;
    trial.evaluations = 0;
    const Outcome outcome = attempt(trial, kernel, pair, control, tau, state.q, state.v, state.a, size, t, h, error,
                                    rejected);
    const bool accepted = outcome == Outcome::accepted;
    bool usable = accepted;
    const double t_new = t + h;
    if (accepted && trial.has_end) {
      a_new = trial.end.tail(nv);
    } else if (accepted) {
      ++trial.evaluations;
      usable = kernel.acceleration(0, t_new, trial.q_new, trial.v_new, tau, a_new);
    }
    if (!usable) {
      if (own) {  // what the Python loop counted before it raised
        state.outcome = accepted ? Outcome::raised : outcome;
        state.failed_step = h;
        state.rejected += rejected;
        if (accepted) {
          state.accepted += 1;
          state.smallest = std::min(state.smallest, h);
          state.largest = std::max(state.largest, h);
        }
      }
      break;
    }
    // the grid samples in (t, t_new] (StepLoop.grid_between): the end state on a grid time, else the dense output
    const long low = floor_index(t / grid.dt + grid.slack) + 1;
    const long high = t_new >= grid.duration - grid.slack * grid.dt
                          ? grid.steps
                          : std::min(floor_index(t_new / grid.dt + grid.slack), grid.steps);
    if (high >= low) {
      segment.fit(group, pair.hermite, t, state.q, state.v, &state.a, t_new, trial.q_new, trial.v_new, &a_new);
      for (long k = low; k <= high; ++k) {
        const double time = k == grid.steps ? grid.duration : static_cast<double>(k) * grid.dt;
        const long row = k - first;
        if (row >= qs.rows()) {
          qs.conservativeResize(2 * row + 2, Eigen::NoChange);
          vs.conservativeResize(2 * row + 2, Eigen::NoChange);
        }
        if (std::abs(time - t_new) <= grid.slack * grid.dt) {
          qs.row(row) = trial.q_new.transpose();
          vs.row(row) = trial.v_new.transpose();
        } else {
          segment.state(group, time, q_sample, v_sample);
          qs.row(row) = q_sample.transpose();
          vs.row(row) = v_sample.transpose();
        }
        count = static_cast<int>(row + 1);
      }
    }
    state.step_size = next_step(control, h, error, state.step_size, state.previous_error, rejected > 0);
    state.previous_error = error;
    state.accepted += 1;
    state.rejected += rejected;
    state.evaluations += trial.evaluations;
    state.steps += 1;
    state.smallest = std::min(state.smallest, h);
    state.largest = std::max(state.largest, h);
    state.t = t_new;
    state.q = trial.q_new;
    state.v = trial.v_new;
    state.a = a_new;
  }
  return count;
}

}  // namespace pinstab
