// The contact features of collision-shape pairs (cpp/geometry_features.hpp).
#include "geometry_features.hpp"

#include <coal/distance.h>
#include <coal/shape/geometric_shapes.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <pinocchio/algorithm/geometry.hpp>

namespace pinstab {

namespace {

// A plane: its unit normal (into shape A) and a point of it [m] (world).
struct Plane {
  Eigen::Vector3d normal, point;
};

// The outward unit normal and centre [m] (world) of the face of a box placed at `placed` whose normal is nearest to
// `normal` (world): the plane a shape touching that face rests on.
Plane box_face(const coal::Box& box, const pinocchio::SE3& placed, const Eigen::Vector3d& normal) {
  const Eigen::Vector3d local = placed.rotation().transpose() * normal;
  Eigen::Index axis = 0;  // the first of equal largest components
  for (Eigen::Index i = 1; i < 3; ++i) {
    if (std::abs(local(i)) > std::abs(local(axis))) axis = i;
  }
  Eigen::Vector3d outward = Eigen::Vector3d::Zero();
  outward(axis) = local(axis) > 0.0 ? 1.0 : -1.0;
  return {placed.rotation() * outward, placed.act(Eigen::Vector3d(outward.cwiseProduct(box.halfSide)))};
}

// The plane separating two placed shapes: coal's normal (into A) and B's nearest point; a box B's face nearest to it.
Plane separating_plane(const coal::CollisionGeometry& a, const pinocchio::SE3& placed_a,
                       const coal::CollisionGeometry& b, const pinocchio::SE3& placed_b) {
  coal::DistanceResult result;
  coal::distance(&a, coal::Transform3s(placed_a.rotation(), placed_a.translation()), &b,
                 coal::Transform3s(placed_b.rotation(), placed_b.translation()), coal::DistanceRequest(), result);
  const Eigen::Vector3d normal = -result.normal;  // coal's runs from A to B
  if (b.getNodeType() == coal::GEOM_BOX) return box_face(static_cast<const coal::Box&>(b), placed_b, normal);
  return {normal, result.nearest_points[1]};
}

// Whether the bounding spheres of two placed shapes come within `margin` [m] (a half-space B: always).
bool near(const coal::CollisionGeometry& a, const pinocchio::SE3& placed_a, const coal::CollisionGeometry& b,
          const pinocchio::SE3& placed_b, double margin) {
  if (b.getNodeType() == coal::GEOM_HALFSPACE) return true;
  const double apart = (placed_a.act(a.aabb_center) - placed_b.act(b.aabb_center)).norm();
  return apart <= a.aabb_radius + b.aabb_radius + margin;
}

// Appends a pair's features (every point: all; else those within its margin of the nearest one).
void measure(const ShapePair& pair, const coal::CollisionGeometry& a, const pinocchio::SE3& placed_a,
             const Plane& plane, double side_sine, bool all, std::vector<int>& indices, std::vector<double>& gaps,
             std::vector<Eigen::Vector3d>& worlds) {
  const Eigen::Index count = pair.points.rows();
  const bool cylinder = a.getNodeType() == coal::GEOM_CYLINDER;
  // a cylinder on its side (its axis, z, within the tilt of the plane) counts its end caps' centres, else its rims
  const bool side = std::abs(placed_a.rotation().col(2).dot(plane.normal)) <= side_sine;
  std::vector<double> measured(count);
  std::vector<Eigen::Vector3d> placed(count);
  double least = std::numeric_limits<double>::infinity();
  for (Eigen::Index k = 0; k < count; ++k) {
    placed[k] = placed_a.act(Eigen::Vector3d(pair.points.row(k).transpose()));
    measured[k] = plane.normal.dot(placed[k] - plane.point) - pair.radii(k);
    if (cylinder && (k < 2) != side) measured[k] = std::numeric_limits<double>::infinity();
    least = std::min(least, measured[k]);
  }
  for (Eigen::Index k = 0; k < count; ++k) {
    if (!all && !(measured[k] <= least + pair.margin)) continue;
    indices.push_back(static_cast<int>(k));
    gaps.push_back(measured[k]);
    worlds.push_back(placed[k]);
  }
}

}  // namespace

FoundFeatures geometry_features(const pinocchio::Model& model, pinocchio::Data& data,
                                const pinocchio::GeometryModel& geometry, pinocchio::GeometryData& geometry_data,
                                const VectorXd& q, const std::vector<ShapePair>& pairs, double side_sine, int pair) {
  if (q.size() != model.nq) throw std::invalid_argument("q: a configuration of another model");
  if (pair >= static_cast<int>(pairs.size())) throw std::invalid_argument("pair: no such pair");
  for (const ShapePair& shapes : pairs) {
    if (shapes.a < 0 || shapes.b < 0 || shapes.a >= static_cast<int>(geometry.ngeoms) ||
        shapes.b >= static_cast<int>(geometry.ngeoms) || shapes.points.cols() != 3 ||
        shapes.radii.size() != shapes.points.rows()) {
      throw std::invalid_argument("pairs: a pair of another geometry model or with mismatched points");
    }
  }
  pinocchio::updateGeometryPlacements(model, data, geometry, geometry_data, q);
  FoundFeatures found;
  std::vector<int> owners, indices;
  std::vector<double> gaps;
  std::vector<Eigen::Vector3d> worlds;
  std::vector<Plane> planes;
  const int first = pair < 0 ? 0 : pair, last = pair < 0 ? static_cast<int>(pairs.size()) : pair + 1;
  for (int p = first; p < last; ++p) {
    const ShapePair& shapes = pairs[p];
    const coal::CollisionGeometry& a = *geometry.geometryObjects[shapes.a].geometry;
    const coal::CollisionGeometry& b = *geometry.geometryObjects[shapes.b].geometry;
    const pinocchio::SE3 &placed_a = geometry_data.oMg[shapes.a], &placed_b = geometry_data.oMg[shapes.b];
    if (pair < 0 && !near(a, placed_a, b, placed_b, shapes.margin)) continue;
    if (shapes.round) {
      found.round.push_back(p);
      continue;
    }
    const Plane plane = separating_plane(a, placed_a, b, placed_b);
    measure(shapes, a, placed_a, plane, side_sine, pair >= 0, indices, gaps, worlds);
    owners.resize(indices.size(), p);
    planes.resize(indices.size(), plane);
  }
  const Eigen::Index n = static_cast<Eigen::Index>(indices.size());
  found.pair = Eigen::Map<const VectorXi>(owners.data(), n);
  found.index = Eigen::Map<const VectorXi>(indices.data(), n);
  found.gap = Eigen::Map<const VectorXd>(gaps.data(), n);
  found.normal.resize(n, 3);
  found.point.resize(n, 3);
  found.world.resize(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    found.normal.row(i) = planes[i].normal.transpose();
    found.point.row(i) = planes[i].point.transpose();
    found.world.row(i) = worlds[i].transpose();
  }
  return found;
}

}  // namespace pinstab
