// A run's drift and energy series (pinstab.series.StateSeries.drift_and_energy), compiled for scenes whose
// constraints are all point or planar-point closures: one kinematics pass per sample instead of a Python pass over
// every closure.
#pragma once

#include <tuple>

#include "kernels.hpp"

namespace pinstab {

// The closures' points and rows (pinstab.constraints.loops.FrameClosure.sides and .selection).
struct ClosurePoints {
  VectorXi joints_a, joints_b;     // (closures) the joints carrying each side's point (0: the world)
  Eigen::MatrixXd local_a, local_b;  // (closures, 3) the points in their joints' frames [m]
  Eigen::MatrixXd selection;       // (rows, 3) each row's direction (world axes)
  VectorXi owner;                  // (rows) the closure of each row
};

// Per sample (rows of qs, vs): max |phi| over the rows [m], max |G v| [m/s] and the total energy, kinetic plus
// gravity's [J] (Pinocchio's computeKineticEnergy and computePotentialEnergy); NaN where q or v is not finite.
// Computes in `data` (overwritten).
std::tuple<VectorXd, VectorXd, VectorXd> closure_series(const pinocchio::Model& model, pinocchio::Data& data,
                                                        const ClosurePoints& points, const RowMatrix& qs,
                                                        const RowMatrix& vs);

}  // namespace pinstab
