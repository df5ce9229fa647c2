// Explicit Runge-Kutta steps of a tableau on the configuration group (the only place their sums are:
// pinstab.integration.schemes.ExplicitRungeKutta calls Trial) and error-controlled steps of an embedded pair
// (pinstab.integration.adaptive) on a model whose joints all have one coordinate (q (+) dq = q + dq): the error norm,
// the step-size control and the grid samples from the dense output. The Python loop calls the same trial, error
// norm, control and dense output, with its own evaluation per stage: the two loops take the same steps to the last
// bit (compiled with -ffp-contract=off).
#pragma once

#include "group.hpp"

namespace pinstab {

// The pair's coefficients (pinstab.integration.tableaus via schemes.ExplicitRungeKutta, passed at construction) and
// the dense output's Hermite matrix (pinstab.integration.dense.QUINTIC; empty for steps without error control).
struct Pair {
  VectorXd nodes;               // c_i (s,)
  Eigen::MatrixXd coupling;     // a_ij (s x s), strictly lower triangular
  VectorXd weights;             // b_j (s,)
  Eigen::MatrixXd estimators;   // none, one or two rows, s + 1 columns (the last: the new point's derivative)
  Eigen::MatrixXd hermite;      // (6 x 6): ends (0, h v0, h^2 a0, q1 - q0, h v1, h^2 a1) -> coefficients of u^k
  int stages() const { return static_cast<int>(nodes.size()); }
  bool needs_end() const;       // an estimator weighs the new point's derivative (first same as last)
};

// The tolerances and the constants of pinstab.integration.adaptive (passed from there).
struct Control {
  double rtol, atol;
  double safety, min_factor, max_factor, min_step, pi_alpha, pi_beta, estimator_mix;
  double exponent;  // -1 / (estimator order + 1)
};

// The step [s] after an accepted step of h [s] with error `error` ([-]; the step proposed was `proposed` [s], the
// last accepted error `previous`): proportional-integral control, no growth right after a rejection.
double next_step(const Control& control, double h, double error, double proposed, double previous, bool rejected);
// The shortened step [s] after a rejected step of h [s] with error `error` [-] (not finite: MIN_FACTOR h).
double shrink(const Control& control, double h, double error);

// The polynomial coefficients (rows: powers of u) taking the Hermite values `ends` (rows) through `inverse`.
void hermite_coefficients(const Eigen::Ref<const Eigen::MatrixXd>& inverse, const Eigen::Ref<const RowMatrix>& ends,
                          Eigen::Ref<RowMatrix> coefficients);
// (increment, rate) of that polynomial at u = (t - t0) / h (rate: d/dt, 0 at h = 0).
void hermite_state(const Eigen::Ref<const RowMatrix>& coefficients, double u, double h, Eigen::Ref<VectorXd> increment,
                   Eigen::Ref<VectorXd> rate);

// One trial step of the pair on the group of `group` (nullptr: q (+) dq = q + dq).
class Trial {
 public:
  Trial(const Pair& pair, int nv, const pinocchio::Model* group = nullptr);
  // The step of h [s] from (q, v) at t [s] with a = a(t, q, v), stage i evaluated by kernel.acceleration(i, ...) under
  // tau: fills q_new, v_new, the stage slopes (rows: [velocity slope in the start's tangent space | acceleration])
  // and, with `with_end`, the new point's slope (its acceleration evaluated as stage 0). False when an evaluation is
  // not to be used.
  bool take(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, const VectorXd& a, double t,
            double h, bool with_end);
  // The largest scaled error [-] of the step of h [s] (DOP853: Hairer's combination of its two estimators), each
  // coordinate scaled by atol + rtol max(size, size_new) (2 nv: |y| before and after).
  double error(const Control& control, const VectorXd& size, const VectorXd& size_new, double h) const;

  VectorXd q_new, v_new, end;  // end: [velocity | acceleration] at the new point (when needed)
  RowMatrix slopes;
  long evaluations = 0;

 private:
  const Pair& pair_;
  int nv_;
  Group group_;
  VectorXd increment_, q_, v_, a_;
};

// The run's time grid (stepping.TimeGrid) and where the compiled run must hand back to Python.
struct Grid {
  double dt, duration, slack;  // slack: stepping.GRID_SLACK
  long steps;
};
struct Stops {
  double t_stop;     // the chunk's end [s]
  double due;        // the passage watch's next sample [s]
  double crossing;   // a predicted singular crossing [s] (NaN: none) ...
  double horizon;    // ... planned for when within this many steps (passages.HORIZON)
};

// The controller's state carried between steps and what it counted.
struct ControlState {
  double t, step_size, previous_error;
  VectorXd q, v, a;  // a: the acceleration at (t, q, v)
  long accepted = 0, rejected = 0, evaluations = 0, steps = 0;
  double smallest = INFINITY, largest = 0.0;
};

// Accepted steps from `state` until t_stop, the watch's due time, a crossing within the horizon, or an attempt
// the compiled loop cannot finish (an evaluation not to be used, an error that is not finite, a step below
// min_step): the state is left at that step's start for Python to take it. Grid samples in the steps taken
// (consecutive grid steps from `first`) are rows of qs, vs (grown as needed); returns how many.
int adaptive_advance(Kernel& kernel, const Pair& pair, const Control& control, const Grid& grid, const Stops& stops,
                     const VectorXd& tau, ControlState& state, long& first, RowMatrix& qs, RowMatrix& vs);

}  // namespace pinstab
