// The contact features of collision-shape pairs at a configuration (pinstab.contact.geometry.ContactShapes.features),
// compiled: per pair the broad phase (bounding spheres), the separating plane (coal's signed distance; a box's face),
// the gaps of shape A's points to it (a cylinder's by how it lies) and the margin filter. The only place these rules
// are. Round pairs (a sphere against a sphere or a capsule), whose plane is on the line of centres
// (pinstab.contact.round_pairs, which the dynamics re-compute at every state), get the broad phase here and are
// measured in Python.
#pragma once

#include <vector>

#include <pinocchio/multibody/geometry.hpp>

#include "kernels.hpp"

namespace pinstab {

// A pair of shapes (indices in the geometry model) allowed to touch: shape A's feature points (k x 3) [m, A's shape
// frame] with the radius of each (0: a vertex), the margin [m] within which of the nearest one a point counts; a
// round pair's plane is not found here.
struct ShapePair {
  int a = 0, b = 0;
  RowMatrix points;
  VectorXd radii;
  double margin = 0.0;
  bool round = false;
};

// The features found: for each, its pair, its point's index k on shape A, its gap [m] to the separating plane
// (< 0: overlap), the plane's unit normal (into A) and a point of it [m, world] and the point's place [m, world]
// (rows); the round pairs the broad phase keeps (or the one pair asked for), to be measured by the caller.
struct FoundFeatures {
  VectorXi pair, index;
  VectorXd gap;
  RowMatrix normal, point, world;
  std::vector<int> round;
};

// The features of every pair (pair < 0) at configuration q, in pair order, then by point; or every point of pair
// `pair` (no broad phase, no margin; a round pair: listed). Updates data's joint placements and geometry_data's
// shape placements at q. A cylinder counts its end caps' centres when its axis is within asin(side_sine) of the
// plane, else its rim points (its points ordered as pinstab.contact.geometry.shape_points gives them).
FoundFeatures geometry_features(const pinocchio::Model& model, pinocchio::Data& data,
                                const pinocchio::GeometryModel& geometry, pinocchio::GeometryData& geometry_data,
                                const VectorXd& q, const std::vector<ShapePair>& pairs, double side_sine, int pair);

// The pinocchio::GeometryModel wrapped by a Python pin.GeometryModel, and the GeometryData of a Python
// pin.GeometryData of it (cpp/python_data.cpp); std::invalid_argument for another object.
const pinocchio::GeometryModel& python_geometry_model(PyObject* object);
pinocchio::GeometryData& python_geometry_data(PyObject* object, const pinocchio::GeometryModel& geometry);

}  // namespace pinstab
