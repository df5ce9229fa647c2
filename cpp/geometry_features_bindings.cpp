// pinstab._compiled.GeometryFeatures: the contact features of collision-shape pairs (cpp/geometry_features.hpp) for
// pinstab.contact.geometry.ContactShapes, which builds the Feature tuples from its arrays.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <tuple>
#include <utility>
#include <vector>

#include "geometry_features.hpp"
#include "numpy_out.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

// The allowed pairs of a scene's shapes and the rule's constant (the sine of a cylinder's side tilt).
struct GeometryFeatures {
  std::vector<ShapePair> pairs;
  double side_sine = 0.0;
};

}  // namespace

void bind_geometry_features(nb::module_& m) {
  nb::class_<GeometryFeatures>(m, "GeometryFeatures")
      .def(
          "__init__",
          [](GeometryFeatures* self, const std::vector<std::pair<int, int>>& shapes, std::vector<RowMatrix> points,
             std::vector<VectorXd> radii, const std::vector<double>& margins, const std::vector<bool>& round,
             double side_sine) {
            const size_t count = shapes.size();
            if (points.size() != count || radii.size() != count || margins.size() != count || round.size() != count) {
              throw std::invalid_argument("GeometryFeatures: one entry per pair in each list");
            }
            auto* made = new (self) GeometryFeatures{{}, side_sine};
            for (size_t p = 0; p < count; ++p) {
              made->pairs.push_back(ShapePair{shapes[p].first, shapes[p].second, std::move(points[p]),
                                              std::move(radii[p]), margins[p], round[p]});
            }
          },
          "pairs"_a, "points"_a, "radii"_a, "margins"_a, "round"_a, "side_sine"_a,
          "The pairs (shape A, shape B) of a geometry model allowed to touch, with shape A's feature points (k x 3) "
          "[m, its shape frame], their radii (k) [m], each pair's margin [m], whether it is round (its plane not "
          "found here) and the sine of the tilt within which a cylinder lies on its side.")
      .def(
          "find",
          [](const GeometryFeatures& self, nb::handle model, nb::handle data, nb::handle geometry,
             nb::handle geometry_data, const VectorXd& q, int pair) {
            const pinocchio::Model& native = python_model(model.ptr());
            const pinocchio::GeometryModel& shapes = python_geometry_model(geometry.ptr());
            FoundFeatures found =
                geometry_features(native, python_data(data.ptr(), native), shapes,
                                  python_geometry_data(geometry_data.ptr(), shapes), q, self.pairs, self.side_sine, pair);
            return nb::make_tuple(numpy_out(std::move(found.pair)), numpy_out(std::move(found.index)),
                                  numpy_out(std::move(found.gap)), numpy_out(std::move(found.normal)),
                                  numpy_out(std::move(found.point)), numpy_out(std::move(found.world)),
                                  std::move(found.round));
          },
          "model"_a, "data"_a, "geometry"_a, "geometry_data"_a, "q"_a, "pair"_a = -1,
          "(pairs, indices, gaps [m], normals, plane points [m, world], points [m, world], round pairs): the features "
          "of every pair at q (pair -1: after the broad phase, within each pair's margin of its nearest one; the "
          "round pairs the broad phase keeps listed apart, unmeasured) or every point of one pair (a round one: listed); "
          "updates data and geometry_data at q.");
}

}  // namespace pinstab
