// pinstab._compiled's spring-damper (cpp/spring_damper.hpp): its compiled form read from the Python element's dict
// (pinstab.forces.spring_damper.SpringDamper.compiled_form), for the core kernel and for the element's own force.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

#include <stdexcept>
#include <string>

#include "spring_damper.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

SpringDamperSpec spring_damper_spec(nb::dict form, const pinocchio::Model& model) {
  SpringDamperSpec spring{nb::cast<int>(form["frame_a"]), nb::cast<int>(form["frame_b"]),
                          nb::cast<Eigen::Vector3d>(form["point_b"]), nb::cast<double>(form["stiffness"]),
                          nb::cast<double>(form["damping"]), nb::cast<double>(form["rest_length"])};
  const int frames = static_cast<int>(model.nframes);
  if (spring.frame_a < 0 || spring.frame_a >= frames || spring.frame_b >= frames) {
    throw std::invalid_argument("spring-damper: frames " + std::to_string(spring.frame_a) + ", " +
                                std::to_string(spring.frame_b) + " are not both in the model's " +
                                std::to_string(frames) + " (frame_b < 0: the world point)");
  }
  return spring;
}

void bind_spring_damper(nb::module_& m) {
  m.attr("SPRING_COINCIDENT_LENGTH") = kCoincidentLength;  // [m]
  m.def(
      "spring_damper_terms",
      [](nb::handle model, nb::handle data, nb::dict form, const VectorXd& v) {
        const pinocchio::Model& loaded = python_model(model.ptr());
        const SpringDamperSpec spring = spring_damper_spec(form, loaded);
        if (v.size() != loaded.nv) throw std::invalid_argument("spring_damper_terms: v (nv)");
        const SpringLine line = spring_line(loaded, python_data(data.ptr(), loaded), spring);
        const std::optional<SpringDamperTerms> terms = spring_damper_terms(spring, line, v);
        if (!terms) return std::make_tuple(line.difference.norm(), 0.0, std::optional<VectorXd>());
        return std::make_tuple(terms->length, terms->rate, std::optional<VectorXd>(terms->force));
      },
      "model"_a, "data"_a, "form"_a, "v"_a,
      "(length l [m], rate dl/dt [m/s], generalized force (J_a - J_b)^T F [N, N m] (nv,) or None) of a spring-damper "
      "(its compiled form, SpringDamper.compiled_form) at v, from a pin.Data after a Jacobians and placements pass: "
      "F = -(k (l - l0) + c dl/dt) u; None (rate 0) where the points coincide (l < 1e-12 m) and the law needs u.");
}

}  // namespace pinstab
