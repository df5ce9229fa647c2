// pinstab._compiled's projections (cpp/projection.hpp): the least-change correction, the corrections of `projection`
// and `post` with any projector (the core's compiled one, or a Python object's position_step and velocity_projection:
// pinstab.projection), the core's projections and the compiled loop's correction on the core path
// (pinstab.integration.compiled: the corrector of the compiled runs, cpp/step_bindings.cpp).
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/tuple.h>

#include <stdexcept>
#include <string>
#include <tuple>

#include "projection.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

// A Python projector's methods position_step(q, t) -> (dq, max |phi|) and velocity_projection(q, v, t) -> v, and
// refine(on) where it has one, called with the GIL held (an exception they raise propagates unchanged).
class PythonProjections : public Projections {
 public:
  PythonProjections(nb::handle projector, Eigen::Index nv) : projector_(projector), nv_(nv) {}
  bool position_step(const VectorXd& q, double t, VectorXd& step, double& worst) override {
    const nb::tuple result = nb::cast<nb::tuple>(projector_.attr("position_step")(q, t));
    step = sized(result[0], "position_step");
    worst = nb::cast<double>(result[1]);
    return true;
  }
  bool velocity_projection(const VectorXd& q, const VectorXd& v, double t, VectorXd& projected) override {
    projected = sized(projector_.attr("velocity_projection")(q, v, t), "velocity_projection");
    return true;
  }
  bool refine(bool on) override {
    if (!nb::hasattr(projector_, "refine")) return false;
    projector_.attr("refine")(on);
    return true;
  }

 private:
  VectorXd sized(nb::handle array, const char* method) const {
    VectorXd x = nb::cast<VectorXd>(array);
    if (x.size() != nv_) {
      throw std::invalid_argument(std::string("a projector's ") + method + " gave " + std::to_string(x.size()) +
                                  " entries, not nv = " + std::to_string(nv_));
    }
    return x;
  }
  nb::handle projector_;
  Eigen::Index nv_;
};

// The corrections' arguments checked against the model: q (nq), v (nv).
const pinocchio::Model& checked(nb::handle model, const VectorXd& q, const VectorXd* v) {
  const pinocchio::Model& loaded = python_model(model.ptr());
  if (q.size() != loaded.nq || (v != nullptr && v->size() != loaded.nv)) {
    throw std::invalid_argument("a projection: q and v are not of the model's sizes (nq, nv)");
  }
  return loaded;
}

// The core's compiled projections when `projector` is one, else its Python methods; then f(projections).
template <class Function>
auto with_projections(nb::handle projector, const pinocchio::Model& model, Function function) {
  if (nb::isinstance<CoreProjection>(projector)) return function(nb::cast<CoreProjection&>(projector));
  PythonProjections projections(projector, model.nv);
  return function(projections);
}

std::tuple<VectorXd, VectorXd, int, double, int> correct_state(nb::handle projector, nb::handle model, bool post,
                                                               double threshold, double floor, int max_iterations,
                                                               VectorXd q, VectorXd v, double t) {
  const pinocchio::Model& loaded = checked(model, q, &v);
  const Group group(&loaded);
  int iterations = 0;
  double worst = 0.0;
  const CorrectionOutcome outcome = with_projections(projector, loaded, [&](Projections& projections) {
    return correct(projections, group, post, PositionRule{threshold, floor, max_iterations}, t, q, v, iterations,
                   worst);
  });
  return {std::move(q), std::move(v), iterations, worst, static_cast<int>(outcome)};
}

std::tuple<VectorXd, int, double, int> projected_positions(nb::handle projector, nb::handle model, double threshold,
                                                           double floor, int max_iterations, VectorXd q, double t) {
  const pinocchio::Model& loaded = checked(model, q, nullptr);
  const Group group(&loaded);
  int iterations = 0;
  double worst = 0.0;
  const CorrectionOutcome outcome = with_projections(projector, loaded, [&](Projections& projections) {
    return project_positions(projections, group, PositionRule{threshold, floor, max_iterations}, t, q, iterations,
                             worst);
  });
  return {std::move(q), iterations, worst, static_cast<int>(outcome)};
}

}  // namespace

void bind_projection(nb::module_& m) {
  m.def(
      "weighted_correction",
      [](const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, const VectorXd& residual, double cutoff,
         bool refine) {
        if (mass.rows() != mass.cols() || jacobian.cols() != mass.rows() || residual.size() != jacobian.rows()) {
          throw std::invalid_argument("weighted_correction: M (n x n), G (r x n) and r (r)");
        }
        VectorXd change;
        const bool finite = weighted_correction(mass, jacobian, residual, cutoff, change, refine);
        return std::make_tuple(change, finite);
      },
      "mass"_a, "jacobian"_a, "residual"_a, "cutoff"_a, "refine"_a = false,
      "(-M^-1 G^T (G M^-1 G^T)^+ r, finite): the least change in the kinetic metric that removes r to first order "
      "(the pseudo-inverse's eigenvalues at most cutoff times the largest left out; refine: refined by the singular "
      "values of G L^-T where that leaves more than rounding of r, cpp/projection.hpp LeastChange); finite False: M "
      "not positive definite or the rows not finite (the change is NaN).");
  nb::class_<CoreProjection>(m, "CoreProjection")
      .def(nb::init<const CoreKernel&, double>(), "kernel"_a, "cutoff"_a,
           "The projections on a core kernel's rows (its own kinematics pass and M; the pseudo-inverse's cutoff).")
      .def(
          "step_at",
          [](CoreProjection& self, const VectorXd& q, double t) {
            if (q.size() != self.model().nq) throw std::invalid_argument("CoreProjection: q is not of size nq");
            VectorXd step;
            double worst = 0.0;
            const bool finite = self.position_step(q, t, step, worst);
            return std::make_tuple(step, worst, finite);
          },
          "q"_a, "t"_a,
          "(dq, max |phi| [m or rad], finite): the Gauss-Newton step -M^-1 G^T (G M^-1 G^T)^+ phi over the holonomic "
          "rows at (q, t).")
      .def(
          "velocities_at",
          [](CoreProjection& self, const VectorXd& q, const VectorXd& v, double t) {
            if (q.size() != self.model().nq || v.size() != self.model().nv) {
              throw std::invalid_argument("CoreProjection: q and v are not of the model's sizes (nq, nv)");
            }
            VectorXd projected;
            const bool finite = self.velocity_projection(q, v, t, projected);
            return std::make_tuple(projected, finite);
          },
          "q"_a, "v"_a, "t"_a, "(v - M^-1 G^T (G M^-1 G^T)^+ (G v + g_t), finite) at (q, t) [m/s or rad/s].");
  m.def("correct", &correct_state, "projector"_a, "model"_a, "post"_a, "threshold"_a, "floor"_a, "max_iterations"_a,
        "q"_a, "v"_a, "t"_a,
        "(q, v, iterations, worst, outcome): the correction of `projection` (post False) or `post` at t [s] with a "
        "CoreProjection or a Python projector (position_step, velocity_projection); outcome 0 done, 1 the "
        "Gauss-Newton iteration did not converge (worst: its last residual [m or rad]), 2 not finite.");
  m.def("project_positions", &projected_positions, "projector"_a, "model"_a, "threshold"_a, "floor"_a,
        "max_iterations"_a, "q"_a, "t"_a,
        "(q, iterations, worst, outcome): Gauss-Newton on phi(q) = 0 at t [s] (the stopping rule of "
        "pinstab.projection.project_positions); outcome as correct's.");
  nb::class_<CoreCorrection, Corrector>(m, "CoreCorrection")
      .def(
          "__init__",
          [](CoreCorrection* self, CoreProjection& projections, bool post, double threshold, double floor,
             int max_iterations) {
            new (self) CoreCorrection(projections, post, PositionRule{threshold, floor, max_iterations});
          },
          "projections"_a, "post"_a, "threshold"_a, "floor"_a, "max_iterations"_a,
          nb::keep_alive<1, 2>(),  // the projections live as long as the correction
          "The correction after each step of a compiled run (SchemeStep.run, RungeKutta.run: corrector) on a core "
          "kernel's rows: `projection` (post False: Gauss-Newton to threshold [m or rad], rounding floor [m or rad], "
          "max_iterations) or `post`.");
}

}  // namespace pinstab
