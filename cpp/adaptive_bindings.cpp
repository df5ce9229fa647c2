// pinstab._compiled.AdaptivePair: the error-controlled compiled loop (cpp/adaptive.cpp) for
// pinstab.integration.compiled.CompiledAdaptive, and the error norm and control that pinstab.integration.adaptive
// calls (its trial steps: RungeKutta, cpp/step_bindings.cpp); hermite_coefficients, hermite_state:
// pinstab.integration.dense's.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

#include <optional>
#include <stdexcept>

#include "adaptive.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

struct AdaptivePair {
  Pair pair;
  Control control;
};

// q, v and a of one size (q (+) dq = q + dq), that of the kernel when there is one.
void check_state(const VectorXd& q, const VectorXd& v, const VectorXd& a, long nv) {
  if (q.size() != nv || v.size() != nv || a.size() != nv) {
    throw std::invalid_argument("AdaptivePair: q, v and a must have one entry per velocity coordinate");
  }
}

nb::tuple run(const AdaptivePair& self, Kernel& kernel, const VectorXd& tau, double t, const VectorXd& q,
              const VectorXd& v, const VectorXd& a, double step_size, double previous_error, double dt,
              double duration, long steps, double slack, double t_stop, double due, double crossing, double horizon) {
  check_state(q, v, a, kernel.nv());
  ControlState state{t, step_size, previous_error, q, v, a};
  const Grid grid{dt, duration, slack, steps};
  const Stops stops{t_stop, due, crossing, horizon};
  RowMatrix qs(8, q.size()), vs(8, v.size());
  long first = 0;
  int samples;
  {
    nb::gil_scoped_release released;
    samples = adaptive_advance(kernel, self.pair, self.control, grid, stops, tau, state, first, qs, vs);
  }
  RowMatrix kept_q = qs.topRows(samples), kept_v = vs.topRows(samples);
  return nb::make_tuple(state.steps, state.t, state.q, state.v, state.a, state.step_size, state.previous_error,
                        state.accepted, state.rejected, state.evaluations, state.smallest, state.largest, first,
                        kept_q, kept_v);
}

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
             const Eigen::MatrixXd& estimators, const Eigen::MatrixXd& hermite, nb::dict constants) {
            auto c = [&](const char* key) { return nb::cast<double>(constants[key]); };
            if (estimators.rows() < 1 || estimators.rows() > 2 || estimators.cols() != nodes.size() + 1 ||
                coupling.rows() != nodes.size() || coupling.cols() != nodes.size() || weights.size() != nodes.size() ||
                hermite.rows() != 6 || hermite.cols() != 6) {
              throw std::invalid_argument("AdaptivePair: inconsistent tableau shapes");
            }
            new (self) AdaptivePair{Pair{nodes, coupling, weights, estimators, hermite},
                                    Control{c("rtol"), c("atol"), c("safety"), c("min_factor"), c("max_factor"),
                                            c("min_step"), c("pi_alpha"), c("pi_beta"), c("estimator_mix"),
                                            c("exponent")}};
          },
          "nodes"_a, "coupling"_a, "weights"_a, "estimators"_a, "hermite"_a, "constants"_a,
          "An embedded pair (c, a, b, estimators with the new point's column, the quintic Hermite matrix) and the "
          "control's constants (dict: rtol, atol, safety, min_factor, max_factor, min_step, pi_alpha, pi_beta, "
          "estimator_mix, exponent).")
      .def("run", &run, "kernel"_a, "tau"_a, "t"_a, "q"_a, "v"_a, "a"_a, "step_size"_a, "previous_error"_a, "dt"_a,
           "duration"_a, "steps"_a, "slack"_a, "t_stop"_a, "due"_a, "crossing"_a, "horizon"_a,
           "(steps, t, q, v, a, step_size, previous_error, accepted, rejected, evaluations, smallest, largest, first, "
           "qs, vs): accepted steps from (t, q, v, a) until t_stop, the due time or a crossing within horizon steps, "
           "or an attempt left to Python; the grid samples of grid steps first, first + 1, ... (rows of qs, vs).")
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
