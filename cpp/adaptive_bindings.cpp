// pinstab._compiled.AdaptivePair: the error-controlled compiled loop (cpp/adaptive.cpp) for
// pinstab.integration.compiled.CompiledAdaptive, and the error norm and control that pinstab.integration.adaptive
// calls (its trial steps: RungeKutta, cpp/step_bindings.cpp); hermite_coefficients, hermite_state:
// pinstab.integration.dense's.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

#include <memory>
#include <optional>
#include <stdexcept>

#include "callback_kernel.hpp"
#include "implicit.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

nb::object newton_counts(const Pair& pair, const Trial* trial);  // cpp/step_bindings.cpp

namespace {

struct AdaptivePair {
  Pair pair;
  Control control;
  NewtonSettings newton;         // an implicit pair's: the control's tolerances, kappa and max_iterations given
  std::unique_ptr<Trial> trial;  // its trial steps' (an ImplicitTrial's Newton state carries over from call to call)

  // The trial step on the kernel's group.
  Trial& trial_of(Kernel& kernel) {
    if (!trial || trial->nv() != kernel.nv()) trial = make_trial(pair, kernel.nv(), kernel.group(), newton);
    trial->use_group(kernel.group());
    return *trial;
  }
};

using Matrices = std::tuple<Eigen::MatrixXd, Eigen::MatrixXd, Eigen::MatrixXd>;

Hermite hermite_of(const Matrices& matrices) {
  const auto& [quintic, quartic, cubic] = matrices;
  if (quintic.rows() != 6 || quintic.cols() != 6 || quartic.rows() != 5 || quartic.cols() != 5 || cubic.rows() != 4 ||
      cubic.cols() != 4) {
    throw std::invalid_argument("hermite: the quintic (6 x 6), quartic (5 x 5) and cubic (4 x 4) Hermite matrices");
  }
  return Hermite{quintic, quartic, cubic};
}

// q of the kernel's group's nq (of nv without one), v and a of nv.
void check_state(Kernel& kernel, const VectorXd& q, const VectorXd& v, const VectorXd& a) {
  const long nq = kernel.group() != nullptr ? kernel.group()->nq : kernel.nv();
  if (q.size() != nq || v.size() != kernel.nv() || a.size() != kernel.nv()) {
    throw std::invalid_argument("AdaptivePair: q must have nq entries, v and a one per velocity coordinate");
  }
}

nb::tuple run(AdaptivePair& self, nb::handle kernel_spec, const VectorXd& tau, double t, const VectorXd& q,
              const VectorXd& v, const VectorXd& a, double step_size, double previous_error, double dt,
              double duration, long steps, double slack, double t_stop, double due, double crossing, double horizon) {
  RunKernel kernel(kernel_spec, static_cast<int>(v.size()));
  check_state(*kernel, q, v, a);
  ControlState state{t, step_size, previous_error, q, v, a};
  const Grid grid{dt, duration, slack, steps};
  const Stops stops{t_stop, due, crossing, horizon};
  RowMatrix qs(8, q.size()), vs(8, v.size());
  long first = 0;
  int samples;
  Trial& trial = self.trial_of(*kernel);
  if (kernel.callback) {  // its evaluations hold the GIL
    samples = adaptive_advance(*kernel, trial, self.pair, self.control, grid, stops, tau, state, first, qs, vs);
  } else {
    nb::gil_scoped_release released;
    samples = adaptive_advance(*kernel, trial, self.pair, self.control, grid, stops, tau, state, first, qs, vs);
  }
  RowMatrix kept_q = qs.topRows(samples), kept_v = vs.topRows(samples);
  nb::object raised = nb::none();
  if (state.outcome == Outcome::raised) raised = kernel.raised();
  return nb::make_tuple(state.steps, state.t, state.q, state.v, state.a, state.step_size, state.previous_error,
                        state.accepted, state.rejected, state.evaluations, state.smallest, state.largest, first,
                        kept_q, kept_v, state.outcome == Outcome::too_short ? state.failed_step : NAN, raised);
}

nb::tuple attempt_step(AdaptivePair& self, nb::handle kernel_spec, const VectorXd& tau, const VectorXd& q,
                       const VectorXd& v, const VectorXd& a, double t, double h) {
  RunKernel kernel(kernel_spec, static_cast<int>(v.size()));
  check_state(*kernel, q, v, a);
  Trial& trial = self.trial_of(*kernel);
  VectorXd size(2 * v.size());
  size << magnitude(trial.group(), q), v.cwiseAbs();
  double error = 0.0;
  long rejected = 0;
  const Outcome outcome = attempt(trial, *kernel, self.pair, self.control, tau, q, v, a, size, t, h, error, rejected);
  const bool accepted = outcome == Outcome::accepted;
  return nb::make_tuple(static_cast<int>(outcome), h, error, rejected, trial.q_new, trial.v_new, trial.slopes,
                        accepted && trial.has_end ? nb::cast(trial.end) : nb::none(),
                        outcome == Outcome::raised ? kernel.raised() : nb::none());
}

// The dense output of one step (pinstab.integration.dense.Segment), holding the pin.Model of its group.
struct PythonSegment {
  nb::object model;
  Group group;
  Segment segment;
};

double error(const AdaptivePair& self, const VectorXd& size, const VectorXd& size_new, const RowMatrix& slopes,
             std::optional<VectorXd> end, double h) {
  const int nv = static_cast<int>(slopes.cols()) / 2;
  if (slopes.rows() != self.pair.stages() || size.size() != 2 * nv || size_new.size() != 2 * nv ||
      end.has_value() != self.pair.needs_end() || (end && end->size() != 2 * nv)) {
    throw std::invalid_argument("AdaptivePair.error: slopes (stages x 2 nv), sizes (2 nv) and the end slope "
                                "(2 nv, when an estimator weighs it) do not match");
  }
  Trial trial(self.pair, nv);
  trial.slopes = slopes;
  if (end) trial.end = *end;
  return trial.error(self.control, size, size_new, h);
}

}  // namespace

void bind_adaptive(nb::module_& m) {
  nb::class_<AdaptivePair>(m, "AdaptivePair")
      .def(
          "__init__",
          [](AdaptivePair* self, const VectorXd& nodes, const Eigen::MatrixXd& coupling, const VectorXd& weights,
             const Eigen::MatrixXd& estimators, const Matrices& matrices, nb::dict constants) {
            const Hermite hermite = hermite_of(matrices);
            auto c = [&](const char* key) { return nb::cast<double>(constants[key]); };
            Pair pair{nodes, coupling, weights, estimators, hermite};
            check_tableau(pair, "AdaptivePair");
            if (estimators.rows() < 1 || estimators.rows() > 2 || estimators.cols() != nodes.size() + 1) {
              throw std::invalid_argument("AdaptivePair: one or two estimators of s + 1 entries");
            }
            if (pair.implicit() && !pair.stiffly_accurate()) {
              throw std::invalid_argument("AdaptivePair: an implicit pair must be stiffly accurate (b = last row of a)");
            }
            const Control control{c("rtol"), c("atol"), c("safety"), c("min_factor"), c("max_factor"),
                                  c("min_step"), c("pi_alpha"), c("pi_beta"), c("estimator_mix"), c("exponent")};
            NewtonSettings newton{control.rtol, control.atol, 1.0, 1};
            if (pair.implicit()) {
              newton.kappa = c("newton_kappa");
              newton.max_iterations = nb::cast<int>(constants["newton_iterations"]);
            }
            new (self) AdaptivePair{std::move(pair), control, newton, nullptr};
          },
          "nodes"_a, "coupling"_a, "weights"_a, "estimators"_a, "hermite"_a, "constants"_a,
          "An embedded pair (c, a, b: explicit, or diagonally implicit and stiffly accurate; estimators with the new "
          "point's column, the Hermite matrices) and the control's constants (dict: rtol, atol, safety, min_factor, "
          "max_factor, min_step, pi_alpha, pi_beta, estimator_mix, exponent; for an implicit pair newton_kappa and "
          "newton_iterations, its Newton iteration's, cpp/implicit.hpp).")
      .def_prop_ro(
          "newton", [](const AdaptivePair& self) { return newton_counts(self.pair, self.trial.get()); },
          "An implicit pair's (iterations, jacobians, factorizations, failures, globalized, continuation) over its "
          "steps so far (None: an explicit one).")
      .def("run", &run, "kernel"_a, "tau"_a, "t"_a, "q"_a, "v"_a, "a"_a, "step_size"_a, "previous_error"_a, "dt"_a,
           "duration"_a, "steps"_a, "slack"_a, "t_stop"_a, "due"_a, "crossing"_a, "horizon"_a,
           "(steps, t, q, v, a, step_size, previous_error, accepted, rejected, evaluations, smallest, largest, first, "
           "qs, vs, too_short, raised): accepted steps from (t, q, v, a) until t_stop, the due time or a crossing "
           "within horizon steps, or an attempt left to Python; the grid samples of grid steps first, first + 1, ... "
           "(rows of qs, vs). kernel: a Kernel, or (acceleration(q, v, t, stage), pin.Model or None, refusals) for "
           "the Python evaluation; then too_short: the step [s] that fell below the smallest (else NaN), raised: the "
           "exception an evaluation raised, to raise (else None).")
      .def("attempt", &attempt_step, "kernel"_a, "tau"_a, "q"_a, "v"_a, "a"_a, "t"_a, "h"_a,
           "(outcome, h, error, rejected, q_new, v_new, slopes, end slope or None, raised): the trial steps from "
           "(q, v, a) at t [s] of h [s], shorter after each rejection, until one meets the tolerance (outcome 0), an "
           "evaluation raised (2: raised, the exception), or the step fell below the smallest (3: h); kernel as "
           "run's.")
      .def(
          "next_step",
          [](const AdaptivePair& self, double h, double error, double proposed, double previous, bool rejected) {
            return next_step(self.control, h, error, proposed, previous, rejected);
          },
          "h"_a, "error"_a, "proposed"_a, "previous"_a, "rejected"_a,
          "The step [s] after an accepted step of h [s] (error [-], proposed step [s], last accepted error [-], "
          "whether it followed a rejection).")
      .def(
          "shrink", [](const AdaptivePair& self, double h, double error) { return shrink(self.control, h, error); },
          "h"_a, "error"_a, "The step [s] to try after a rejected step of h [s] with this error [-].")
      .def("error", &error, "size"_a, "size_new"_a, "slopes"_a, "end"_a.none(), "h"_a,
           "The largest scaled error [-] of a step of h [s] from its slopes (and the new point's when an estimator "
           "weighs it), each coordinate scaled by atol + rtol max(size, size_new).");
  nb::class_<PythonSegment>(m, "Segment")
      .def(
          "__init__",
          [](PythonSegment* self, nb::object model, const Matrices& matrices, double t0, const VectorXd& q0,
             const VectorXd& v0, std::optional<VectorXd> a0, double t1, const VectorXd& q1, const VectorXd& v1,
             std::optional<VectorXd> a1) {
            const pinocchio::Model* group = python_group(model);
            const long nq = group != nullptr ? group->nq : v0.size();
            if (q0.size() != nq || q1.size() != nq || v1.size() != v0.size() || (a0 && a0->size() != v0.size()) ||
                (a1 && a1->size() != v0.size()) || (group != nullptr && v0.size() != group->nv)) {
              throw std::invalid_argument("Segment: q0, q1 of nq entries, v0, v1, a0, a1 of nv");
            }
            new (self) PythonSegment{std::move(model), Group(group), Segment()};
            self->segment.fit(self->group, hermite_of(matrices), t0, q0, v0, a0 ? &*a0 : nullptr, t1, q1, v1,
                              a1 ? &*a1 : nullptr);
          },
          "model"_a.none(), "hermite"_a, "t0"_a, "q0"_a, "v0"_a, "a0"_a.none(), "t1"_a, "q1"_a, "v1"_a, "a1"_a.none(),
          "The dense output of a step from (q0, v0, a0) at t0 [s] to (q1, v1, a1) at t1 [s] on the group of a "
          "pin.Model (None: every joint of one coordinate); hermite: (quintic, quartic, cubic) matrices; without "
          "accelerations, cubic.")
      .def_prop_ro("t0", [](const PythonSegment& self) { return self.segment.t0; })
      .def_prop_ro("h", [](const PythonSegment& self) { return self.segment.h; })
      .def_prop_ro("q0", [](const PythonSegment& self) { return self.segment.q0; })
      .def_prop_ro("coefficients", [](const PythonSegment& self) { return self.segment.coefficients; },
                   "(degree + 1, nv): the increment's polynomial, rows: powers of u = (t - t0) / h.")
      .def(
          "state",
          [](PythonSegment& self, double t) {
            VectorXd q, v(self.segment.coefficients.cols());
            self.segment.state(self.group, t, q, v);
            return std::make_tuple(q, v);
          },
          "t"_a, "(q, v) at t [s].");
  m.def(
      "hermite_coefficients",
      [](const Eigen::MatrixXd& inverse, const RowMatrix& ends) {
        if (inverse.cols() != ends.rows()) throw std::invalid_argument("hermite_coefficients: one row per end value");
        RowMatrix coefficients(inverse.rows(), ends.cols());
        hermite_coefficients(inverse, ends, coefficients);
        return coefficients;
      },
      "inverse"_a, "ends"_a, "The coefficients (rows: powers of u) inverse @ ends, summed in order.");
  m.def(
      "hermite_state",
      [](const RowMatrix& coefficients, double u, double h) {
        VectorXd increment(coefficients.cols()), rate(coefficients.cols());
        hermite_state(coefficients, u, h, increment, rate);
        return std::make_tuple(increment, rate);
      },
      "coefficients"_a, "u"_a, "h"_a,
      "(sum_k c_k u^k, sum_k k c_k u^(k-1) / h): the polynomial's value and its rate [per s] (0 at h = 0).");
}

}  // namespace pinstab
