// pinstab._compiled.SchemeStep and RungeKutta: one explicit step of a fixed scheme (cpp/stepping.cpp) or of a
// Runge-Kutta tableau (Trial, cpp/adaptive.cpp) for the Python step loops (pinstab.integration.schemes), the
// stages evaluated by a Python callable: the schemes' arithmetic lives in C++ only.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "callback_kernel.hpp"
#include "implicit.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

// A pin.Model (held) for the group, or None: every joint of one coordinate.
struct GroupModel {
  nb::object model;
  const pinocchio::Model* group = nullptr;

  explicit GroupModel(nb::object python) : model(std::move(python)) {
    if (!model.is_none()) group = &python_model(model.ptr());
  }
  // q (nq) and v (nv) of the model's sizes (without one: of one size).
  void check(const VectorXd& q, const VectorXd& v, const char* where) const {
    const bool sized = group == nullptr ? q.size() == v.size() : q.size() == group->nq && v.size() == group->nv;
    if (!sized) throw std::invalid_argument(std::string(where) + ": q and v are not of the model's sizes (nq, nv)");
  }
};

struct PythonScheme {
  GroupModel model;
  Scheme code;
  SchemeStep scheme;
};

struct PythonTableau {
  GroupModel model;
  Pair pair;
  NewtonSettings newton;  // an implicit tableau's
  std::unique_ptr<Trial> trial;  // its steps' (an ImplicitTrial's Newton state carries over from call to call)

  Trial& trial_of(int nv) {
    if (!trial || trial->nv() != nv) trial = make_trial(pair, nv, model.group, newton);
    return *trial;
  }
};

nb::tuple scheme_step(PythonScheme& self, nb::handle acceleration, nb::handle q_array, nb::handle v_array, double t,
                      double dt) {
  VectorXd q = nb::cast<VectorXd>(q_array), v = nb::cast<VectorXd>(v_array);
  self.model.check(q, v, "SchemeStep.step");
  CallbackKernel kernel(acceleration, static_cast<int>(v.size()), self.model.group);
  kernel.share(q, q_array, v, v_array);  // the stages at the start: the caller's arrays (q, v change after the last)
  if (!self.scheme.take(kernel, VectorXd(), t, dt, q, v)) reraise(kernel.raised(false));
  return nb::make_tuple(std::move(q), std::move(v));
}

// Fixed steps of a compiled run (advance(kernel, qs, vs, correction) -> steps done) from (q, v) on `kernel`
// (RunKernel's: the GIL released for a compiled kernel), each step corrected by `corrector` when one is given: (qs, vs,
// done, the exception a Python evaluation raised or None, the corrections' iterations per step done or None).
template <class Advance>
nb::tuple fixed_run(const GroupModel& model, nb::handle kernel_spec, const VectorXd& q, const VectorXd& v, int steps,
                    Corrector* corrector, Advance advance) {
  model.check(q, v, "run");
  if (steps < 0) throw std::invalid_argument("run: steps must be >= 0");
  RunKernel kernel(kernel_spec, static_cast<int>(v.size()));
  RowMatrix qs(steps, q.size()), vs(steps, v.size());
  std::optional<Correction> correction;
  if (corrector != nullptr) correction.emplace(Correction{*corrector, VectorXi::Zero(steps)});
  Correction* correcting = correction ? &*correction : nullptr;
  int done;
  if (kernel.callback) {
    done = advance(*kernel, qs, vs, correcting);
  } else {
    nb::gil_scoped_release released;
    done = advance(*kernel, qs, vs, correcting);
  }
  RowMatrix kept_q = qs.topRows(done), kept_v = vs.topRows(done);
  nb::object iterations = correction ? nb::cast(VectorXi(correction->iterations.head(done))) : nb::none();
  return nb::make_tuple(kept_q, kept_v, done, kernel.raised(), iterations);
}

nb::tuple scheme_run(PythonScheme& self, nb::handle kernel, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                     double dt, int steps, long start, Corrector* corrector) {
  return fixed_run(self.model, kernel, q, v, steps, corrector,
                   [&](Kernel& evaluation, RowMatrix& qs, RowMatrix& vs, Correction* correction) {
                     return advance(evaluation, self.code, q, v, tau, dt, start, steps, qs, vs, correction);
                   });
}

nb::tuple tableau_run(PythonTableau& self, nb::handle kernel, const VectorXd& q, const VectorXd& v,
                      const VectorXd& tau, double dt, int steps, long start, Corrector* corrector) {
  Trial& trial = self.trial_of(static_cast<int>(v.size()));
  return fixed_run(self.model, kernel, q, v, steps, corrector,
                   [&](Kernel& evaluation, RowMatrix& qs, RowMatrix& vs, Correction* correction) {
                     return advance_tableau(evaluation, trial, q, v, tau, dt, start, steps, qs, vs, correction);
                   });
}

nb::tuple tableau_attempt(PythonTableau& self, nb::handle acceleration, nb::handle q_array, nb::handle v_array,
                          double t, double h, std::optional<VectorXd> first, bool with_end, nb::handle jacobian) {
  const VectorXd q = nb::cast<VectorXd>(q_array), v = nb::cast<VectorXd>(v_array);
  self.model.check(q, v, "RungeKutta.attempt");
  const int nv = static_cast<int>(v.size());
  CallbackKernel kernel(acceleration, nv, self.model.group, nb::handle(), jacobian);
  kernel.share(q, q_array, v, v_array);
  VectorXd a(nv);
  if (first) {
    if (first->size() != nv) throw std::invalid_argument("RungeKutta.attempt: first is not of size nv");
    a = *first;
  } else if (!kernel.acceleration(0, t, q, v, VectorXd(), a)) {
    reraise(kernel.raised(false));
  }
  Trial& trial = self.trial_of(nv);
  if (!trial.take(kernel, VectorXd(), q, v, a, t, h, with_end)) {
    if (trial.unconverged) throw NewtonFailure(dynamic_cast<ImplicitTrial&>(trial).failure(t, h));
    reraise(kernel.raised(false));
  }
  return nb::make_tuple(trial.q_new, trial.v_new, trial.slopes, trial.has_end ? nb::cast(trial.end) : nb::none());
}

}  // namespace

nb::object newton_counts(const Pair& pair, const Trial* trial) {
  if (!pair.implicit()) return nb::none();
  const auto* implicit = dynamic_cast<const ImplicitTrial*>(trial);
  const NewtonCounts counts = implicit == nullptr ? NewtonCounts() : implicit->counts;
  return nb::make_tuple(counts.iterations, counts.jacobians, counts.factorizations, counts.failures, counts.globalized,
                        counts.continuation);
}

namespace {

constexpr const char* RUN_DOC =
    "(qs, vs, done, raised, iterations): up to `steps` steps of dt [s] from (q, v) at grid step `start` (time start "
    "dt) under tau on a Kernel, or on (acceleration(q, v, t, stage), pin.Model or None, refusals): the Python "
    "evaluation, each step's end state corrected by `corrector` (a Corrector: CoreCorrection) when one is given; the "
    "steps before one whose evaluation is not to be used or whose correction cannot be made, the exception that "
    "evaluation raised (to raise; else None) and the corrections' iterations per step done (None without one).";

}  // namespace

void bind_steps(nb::module_& m) {
  nb::exception<NewtonFailure>(m, "NewtonFailure", PyExc_ArithmeticError);
  nb::class_<Corrector>(m, "Corrector",
                        "A correction of the state after each step of a compiled run (its kind: CoreCorrection).");
  nb::class_<PythonScheme>(m, "SchemeStep")
      .def(
          "__init__",
          [](PythonScheme* self, int scheme, nb::object model) {
            if (scheme < 0 || scheme > static_cast<int>(Scheme::rk4)) {
              throw std::invalid_argument("SchemeStep: scheme " + std::to_string(scheme) +
                                          " is not 0 euler, 1 semi-implicit Euler, 2 Heun or 3 RK4");
            }
            GroupModel group(std::move(model));
            const pinocchio::Model* pointer = group.group;
            const Scheme code = static_cast<Scheme>(scheme);
            new (self) PythonScheme{std::move(group), code, SchemeStep(code, pointer)};
          },
          "scheme"_a, "model"_a.none(),
          "A fixed scheme (0 euler, 1 semi-implicit Euler, 2 Heun, 3 RK4) on the group of a pin.Model (None: every "
          "joint of one coordinate, q (+) dq = q + dq).")
      .def("step", &scheme_step, "acceleration"_a, "q"_a, "v"_a, "t"_a, "dt"_a,
           "(q, v) after one step of dt [s] from (q, v) at t [s], stage i evaluated by acceleration(q, v, t, i) -> "
           "(nv,) (its exceptions propagate).")
      .def("run", &scheme_run, "kernel"_a, "q"_a, "v"_a, "tau"_a, "dt"_a, "steps"_a, "start"_a,
           "corrector"_a.none() = nb::none(), RUN_DOC);
  nb::class_<PythonTableau>(m, "RungeKutta")
      .def(
          "__init__",
          [](PythonTableau* self, const VectorXd& nodes, const Eigen::MatrixXd& coupling, const VectorXd& weights,
             nb::object model, std::optional<std::tuple<double, double, double, int>> newton) {
            Pair pair{nodes, coupling, weights, {}, {}};
            check_tableau(pair, "RungeKutta");
            if (pair.implicit() && !newton) throw std::invalid_argument("RungeKutta: an implicit tableau needs newton");
            const auto [rtol, atol, kappa, iterations] = newton.value_or(std::make_tuple(1.0, 1.0, 1.0, 1));
            new (self) PythonTableau{GroupModel(std::move(model)), std::move(pair),
                                     NewtonSettings{rtol, atol, kappa, iterations}, nullptr};
          },
          "nodes"_a, "coupling"_a, "weights"_a, "model"_a.none(), "newton"_a.none() = nb::none(),
          "A tableau (c_i, a_ij lower triangular: strictly, or diagonally implicit below an explicit first stage, b_j) "
          "on the group of a pin.Model (None: every joint of one coordinate); newton: (rtol, atol, kappa, "
          "max_iterations) of an implicit tableau's Newton iteration (cpp/implicit.hpp).")
      .def("attempt", &tableau_attempt, "acceleration"_a, "q"_a, "v"_a, "t"_a, "h"_a, "first"_a.none() = nb::none(),
           "end"_a = false, "jacobian"_a.none() = nb::none(),
           "(q_new, v_new, slopes, end slope or None): the step of h [s] from (q, v) at t [s], stage i evaluated by "
           "acceleration(q, v, t, i) (its exceptions propagate; first: the acceleration at (q, v, t) when known); "
           "slopes: stages x 2 nv, [velocity slope in the start's tangent space | acceleration] per stage; with end, "
           "the new point's slope (its acceleration evaluated as stage 0); jacobian: the compiled Kernel whose Jacobians "
           "an implicit stage's Newton iteration takes (None: differences of acceleration).")
      .def("run", &tableau_run, "kernel"_a, "q"_a, "v"_a, "tau"_a, "dt"_a, "steps"_a, "start"_a,
           "corrector"_a.none() = nb::none(), RUN_DOC)
      .def_prop_ro(
          "newton", [](const PythonTableau& self) { return newton_counts(self.pair, self.trial.get()); },
          "An implicit tableau's (iterations, jacobians, factorizations, failures, globalized, continuation) over its "
          "steps so far (None: an explicit one).");
}

}  // namespace pinstab
