// Explicit Runge-Kutta steps of a tableau on the configuration group (the only place their sums are:
// pinstab.integration.schemes.ExplicitRungeKutta calls Trial) and error-controlled steps of an embedded pair
// (pinstab.integration.adaptive) on the configuration group: the attempt (accept, reject, retry), the error norm, the
// step-size control and the grid samples from the dense output (Segment, pinstab.integration.dense's). The Python
// loop's own steps (a passage's, a correcting method's) are this attempt with the Python evaluation (CallbackKernel):
// the loops take the same steps to the last bit (compiled with -ffp-contract=off).
#pragma once

#include "group.hpp"

namespace pinstab {

// The dense output's Hermite matrices (pinstab.integration.dense's QUINTIC, QUARTIC, CUBIC): ends -> coefficients of
// u^k, the ends (0, h v0, h^2 a0, d1, h r1, h^2 a1), (0, h v0, h^2 a0, d1, h r1), (0, h v0, d1, h r1) (d1: q0 (-) q1,
// r1: v1 in q0's tangent space).
struct Hermite {
  Eigen::MatrixXd quintic, quartic, cubic;
};

// The pair's coefficients (pinstab.integration.tableaus via schemes.ExplicitRungeKutta, passed at construction) and
// the dense output's Hermite matrices (empty for steps without error control).
struct Pair {
  VectorXd nodes;               // c_i (s,)
  Eigen::MatrixXd coupling;     // a_ij (s x s), lower triangular: strictly (explicit) or with a non-zero diagonal
                                // below an explicit first stage (diagonally implicit, cpp/implicit.hpp)
  VectorXd weights;             // b_j (s,)
  Eigen::MatrixXd estimators;   // none, one or two rows, s + 1 columns (the last: the new point's derivative)
  Hermite hermite;
  int stages() const { return static_cast<int>(nodes.size()); }
  bool needs_end() const;       // an estimator weighs the new point's derivative (first same as last)
  bool implicit() const;        // a non-zero diagonal entry: the stages solve for themselves (ImplicitTrial)
  bool stiffly_accurate() const;  // b = the last row of a: the step ends on the last stage
};

// A kernel whose evaluation is the Python loop's own (CallbackKernel): the error-controlled loop takes every decision
// of the Python one with it (a trial whose evaluation refused its state, refused(), is rejected like one of infinite
// error; a non-finite error is a rejection, not a hand-back).
class Refusing {
 public:
  virtual ~Refusing() = default;
  virtual bool refused() const = 0;
};

// The interpolated motion of one step (pinstab.integration.dense.Segment is this one): the increment q0 (-) q(t) in
// the tangent space at q0 as a polynomial in u = (t - t0) / h matching the increment, its rate and its second
// derivative at both ends (quintic; quartic without the end's where the joints are not all of one velocity
// coordinate, its transport needing the derivative of dDifference; cubic without accelerations).
struct Segment {
  double t0 = 0.0, h = 0.0;
  VectorXd q0;
  RowMatrix coefficients;  // rows: powers of u
  // From (q0, v0, a0) at t0 [s] to (q1, v1, a1) at t1 [s] on the group (a0, a1 nullptr: cubic).
  void fit(Group& group, const Hermite& hermite, double t0, const VectorXd& q0, const VectorXd& v0,
           const VectorXd* a0, double t1, const VectorXd& q1, const VectorXd& v1, const VectorXd* a1);
  // (q, v) at t [s].
  void state(Group& group, double t, VectorXd& q, VectorXd& v) const;
};

// |neutral (-) q| (nv,): the size of each coordinate of q in the tangent space (|q| where every joint has one
// coordinate; pinstab.model.ConstrainedModel.magnitude), what a relative tolerance is relative to.
VectorXd magnitude(const Group& group, const VectorXd& q);

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

// One trial step of the pair on the group of `group` (nullptr: q (+) dq = q + dq): an explicit tableau's (the
// stages in turn); an implicit one's solves its stages (ImplicitTrial, cpp/implicit.hpp).
class Trial {
 public:
  Trial(const Pair& pair, int nv, const pinocchio::Model* group = nullptr);
  virtual ~Trial() = default;
  // The step of h [s] from (q, v) at t [s] with a = a(t, q, v), stage i evaluated by kernel.acceleration(i, ...) under
  // tau: fills q_new, v_new, the stage slopes (rows: [velocity slope in the start's tangent space | acceleration])
  // and, with `with_end`, the new point's slope (its acceleration evaluated as stage 0; has_end tells it is filled).
  // False when an evaluation is not to be used, or (unconverged true) when an implicit stage was not solved.
  virtual bool take(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, const VectorXd& a,
                    double t, double h, bool with_end);
  // Step on the group of `group` from now on (the evaluation of the next call may be another kernel's).
  void use_group(const pinocchio::Model* group);
  // The largest scaled error [-] of the step of h [s] (DOP853: Hairer's combination of its two estimators), each
  // coordinate scaled by atol + rtol max(size, size_new) (2 nv: |y| before and after).
  double error(const Control& control, const VectorXd& size, const VectorXd& size_new, double h) const;

  Group& group() { return group_; }
  int nv() const { return nv_; }  // the tangent space's dimension it steps in

  VectorXd q_new, v_new, end;  // end: [velocity | acceleration] at the new point (when has_end)
  RowMatrix slopes;
  long evaluations = 0;
  bool has_end = false, unconverged = false;

 protected:
  const Pair& pair_;
  int nv_;
  Group group_;
  VectorXd increment_, q_, v_, a_;
};

// Fixed steps of dt [s] of the pair's tableau (ExplicitRungeKutta.step: the first stage evaluated at the step's start)
// from (q, v) at grid step `start`, as advance takes the schemes'.
// The trial takes them (an ImplicitTrial's Newton state carries over from one call to the next).
int advance_tableau(Kernel& kernel, Trial& trial, const VectorXd& q0, const VectorXd& v0, const VectorXd& tau,
                    double dt, long start, int steps, RowMatrix& qs, RowMatrix& vs, Correction* correction = nullptr);

// How an attempt ended: accepted; handed back to the caller (an evaluation of a compiled kernel not to be used, its
// error not finite, its step below min_step: the Python loop takes that step); an evaluation raised (the kernel's
// pending exception, or its refusal when no shorter step may follow); the step fell below min_step.
enum class Outcome { accepted = 0, handed_back = 1, raised = 2, too_short = 3 };

// AdaptiveLoop.attempt: trial steps from (q, v, a) at t [s] (size: the start's |y|, 2 nv) of h [s], shorter after each
// rejection (an error above 1, or an implicit stage not solved), until one meets the tolerance; h and error become the accepted step's (too_short: the step below
// min_step), rejected counts the rejections.
Outcome attempt(Trial& trial, Kernel& kernel, const Pair& pair, const Control& control, const VectorXd& tau,
                const VectorXd& q, const VectorXd& v, const VectorXd& a, const VectorXd& size, double t, double& h,
                double& error, long& rejected);

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
  Outcome outcome = Outcome::handed_back;  // raised, too_short: the Python loop raises (the CallbackKernel's only)
  double failed_step = NAN;                // too_short: the step [s]
};

// Accepted steps from `state` until t_stop, the watch's due time, a crossing within the horizon, or an attempt the
// compiled loop cannot finish (its outcome in state.outcome; the counts of a CallbackKernel's failed attempt added, as
// the Python loop adds them before it raises): the state is left at that step's start. Grid samples in the steps
// taken (consecutive grid steps from `first`) are rows of qs, vs (grown as needed); returns how many. The trial (of
// the pair) takes the steps.
int adaptive_advance(Kernel& kernel, Trial& trial, const Pair& pair, const Control& control, const Grid& grid,
                     const Stops& stops, const VectorXd& tau, ControlState& state, long& first, RowMatrix& qs,
                     RowMatrix& vs);

}  // namespace pinstab
