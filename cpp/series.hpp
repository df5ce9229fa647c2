// A run's drift and energy series (pinstab.series.StateSeries.drift_and_energy), compiled for scenes whose
// constraints all have compiled rows (cpp/core_rows.hpp): one kinematics pass per sample instead of a Python pass over
// every constraint.
#pragma once

#include <tuple>
#include <vector>

#include "core_rows.hpp"
#include "kernels.hpp"

namespace pinstab {

// Per sample (rows of qs, vs at the times ts [s]): max |phi| over the blocks' rows (block_residual) [m or rad], max |g|
// with g = G v + g_t (block_rate) [m/s or rad/s] and the total energy, kinetic plus gravity's [J] (Pinocchio's
// computeKineticEnergy and computePotentialEnergy); NaN where q or v is not finite. Computes in `data` (overwritten).
std::tuple<VectorXd, VectorXd, VectorXd> closure_series(const pinocchio::Model& model, pinocchio::Data& data,
                                                        const std::vector<RowBlock>& blocks, const RowMatrix& qs,
                                                        const RowMatrix& vs, const VectorXd& ts);

}  // namespace pinstab
