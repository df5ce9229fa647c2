// pinstab._compiled.SchemeStep and RungeKutta: one explicit step of a fixed scheme (cpp/stepping.cpp) or of a
// Runge-Kutta tableau (Trial, cpp/adaptive.cpp) for the Python step loops (pinstab.integration.schemes), the
// stages evaluated by a Python callable: the schemes' arithmetic lives in C++ only.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

#include <optional>
#include <stdexcept>
#include <string>

#include "adaptive.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

// The evaluation of a Python step: acceleration(q, v, t, stage) -> (nv,) array (pinstab.system.ConstrainedSystem's),
// called with the GIL held (the step never releases it); an exception it raises propagates unchanged to the step's
// caller (nb::python_error). Made for one call and holding the callable borrowed, it keeps no Python object alive:
// no reference cycle runs through C++. The step's start state is passed as the caller's own arrays.
class PythonKernel : public Kernel {
 public:
  PythonKernel(nb::handle acceleration, Eigen::Index nv, const VectorXd& q0, const VectorXd& v0, nb::handle q0_array,
               nb::handle v0_array)
      : acceleration_(acceleration), nv_(nv), q0_(q0), v0_(v0), q0_array_(q0_array), v0_array_(v0_array) {}
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd&, VectorXd& a) override {
    const nb::object result = acceleration_(array(q, q0_, q0_array_), array(v, v0_, v0_array_), t, stage);
    a = nb::cast<VectorXd>(result);
    if (a.size() != nv_) {
      throw std::invalid_argument("the acceleration of a step has " + std::to_string(a.size()) + " entries, not nv = " +
                                  std::to_string(nv_));
    }
    return true;
  }
  int nv() const override { return static_cast<int>(nv_); }

 private:
  static nb::object array(const VectorXd& x, const VectorXd& start, nb::handle start_array) {
    if (&x == &start) return nb::borrow(start_array);
    return nb::cast(VectorXd(x));
  }
  nb::handle acceleration_;
  Eigen::Index nv_;
  const VectorXd &q0_, &v0_;
  nb::handle q0_array_, v0_array_;
};

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
  SchemeStep scheme;
};

struct PythonTableau {
  GroupModel model;
  Pair pair;
};

nb::tuple scheme_step(PythonScheme& self, nb::handle acceleration, nb::handle q_array, nb::handle v_array, double t,
                      double dt) {
  VectorXd q = nb::cast<VectorXd>(q_array), v = nb::cast<VectorXd>(v_array);
  self.model.check(q, v, "SchemeStep.step");
  PythonKernel kernel(acceleration, v.size(), q, v, q_array, v_array);
  self.scheme.take(kernel, VectorXd(), t, dt, q, v);
  return nb::make_tuple(std::move(q), std::move(v));
}

nb::tuple attempt(PythonTableau& self, nb::handle acceleration, nb::handle q_array, nb::handle v_array, double t,
                  double h, std::optional<VectorXd> first, bool with_end) {
  const VectorXd q = nb::cast<VectorXd>(q_array), v = nb::cast<VectorXd>(v_array);
  self.model.check(q, v, "RungeKutta.attempt");
  const int nv = static_cast<int>(v.size());
  PythonKernel kernel(acceleration, nv, q, v, q_array, v_array);
  VectorXd a(nv);
  if (first) {
    if (first->size() != nv) throw std::invalid_argument("RungeKutta.attempt: first is not of size nv");
    a = *first;
  } else {
    kernel.acceleration(0, t, q, v, VectorXd(), a);
  }
  Trial trial(self.pair, nv, self.model.group);
  trial.take(kernel, VectorXd(), q, v, a, t, h, with_end);
  return nb::make_tuple(trial.q_new, trial.v_new, trial.slopes, with_end ? nb::cast(trial.end) : nb::none());
}

}  // namespace

void bind_steps(nb::module_& m) {
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
            new (self) PythonScheme{std::move(group), SchemeStep(static_cast<Scheme>(scheme), pointer)};
          },
          "scheme"_a, "model"_a.none(),
          "A fixed scheme (0 euler, 1 semi-implicit Euler, 2 Heun, 3 RK4) on the group of a pin.Model (None: every "
          "joint of one coordinate, q (+) dq = q + dq).")
      .def("step", &scheme_step, "acceleration"_a, "q"_a, "v"_a, "t"_a, "dt"_a,
           "(q, v) after one step of dt [s] from (q, v) at t [s], stage i evaluated by acceleration(q, v, t, i) -> "
           "(nv,) (its exceptions propagate).");
  nb::class_<PythonTableau>(m, "RungeKutta")
      .def(
          "__init__",
          [](PythonTableau* self, const VectorXd& nodes, const Eigen::MatrixXd& coupling, const VectorXd& weights,
             nb::object model) {
            if (nodes.size() < 1 || coupling.rows() != nodes.size() || coupling.cols() != nodes.size() ||
                weights.size() != nodes.size()) {
              throw std::invalid_argument("RungeKutta: nodes (s), coupling (s x s) and weights (s) of one tableau");
            }
            new (self) PythonTableau{GroupModel(std::move(model)), Pair{nodes, coupling, weights, {}, {}}};
          },
          "nodes"_a, "coupling"_a, "weights"_a, "model"_a.none(),
          "An explicit tableau (c_i, a_ij strictly lower triangular, b_j) on the group of a pin.Model (None: every "
          "joint of one coordinate).")
      .def("attempt", &attempt, "acceleration"_a, "q"_a, "v"_a, "t"_a, "h"_a, "first"_a.none() = nb::none(),
           "end"_a = false,
           "(q_new, v_new, slopes, end slope or None): the step of h [s] from (q, v) at t [s], stage i evaluated by "
           "acceleration(q, v, t, i) (its exceptions propagate; first: the acceleration at (q, v, t) when known); "
           "slopes: stages x 2 nv, [velocity slope in the start's tangent space | acceleration] per stage; with end, "
           "the new point's slope (its acceleration evaluated as stage 0).");
}

}  // namespace pinstab
