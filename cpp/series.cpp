// The drift and energy series of a run of compiled rows (see series.hpp).
#include "series.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <pinocchio/algorithm/energy.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

namespace pinstab {

namespace {

// The largest |x_i|; NaN when some x_i is NaN (numpy's max), 0 for none.
double largest(const VectorXd& x) {
  double value = 0.0;
  for (const double entry : x) {
    if (std::isnan(entry)) return entry;
    value = std::max(value, std::abs(entry));
  }
  return value;
}

// The frames the blocks read, each once (their placements are all a sample's pass updates).
std::vector<int> block_frames(const std::vector<RowBlock>& blocks) {
  std::vector<int> frames;
  for (const RowBlock& block : blocks) {
    for (const int frame : {block.frame_a, block.frame_b}) {
      if (frame >= 0) frames.push_back(frame);
    }
  }
  std::sort(frames.begin(), frames.end());
  frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
  return frames;
}

}  // namespace

std::tuple<VectorXd, VectorXd, VectorXd> closure_series(const pinocchio::Model& model, pinocchio::Data& data,
                                                        const std::vector<RowBlock>& blocks, const RowMatrix& qs,
                                                        const RowMatrix& vs, const VectorXd& ts) {
  const long n = qs.rows();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  VectorXd position = VectorXd::Constant(n, nan), velocity = VectorXd::Constant(n, nan),
           energy = VectorXd::Constant(n, nan);
  int rows = 0;
  for (const RowBlock& block : blocks) rows += block.rows();
  const std::vector<int> frames = block_frames(blocks);
  VectorXd phi(rows), g(rows), q(model.nq), v(model.nv);
  for (long k = 0; k < n; ++k) {
    if (!qs.row(k).allFinite() || !vs.row(k).allFinite()) continue;
    q = qs.row(k).transpose();
    v = vs.row(k).transpose();
    pinocchio::forwardKinematics(model, data, q, v);
    for (const int frame : frames) pinocchio::updateFramePlacement(model, data, frame);
    int row = 0;
    for (const RowBlock& block : blocks) {
      block_residual(model, data, block, q, ts(k), phi.segment(row, block.rows()));
      block_rate(model, data, block, v, ts(k), g.segment(row, block.rows()));
      row += block.rows();
    }
    position(k) = largest(phi);
    velocity(k) = largest(g);
    // after the pass at (q, v): Pinocchio's kinetic and potential energy (the same sums its calls at (q, v) make)
    energy(k) = pinocchio::computeKineticEnergy(model, data) + pinocchio::computePotentialEnergy(model, data);
  }
  return {position, velocity, energy};
}

}  // namespace pinstab
