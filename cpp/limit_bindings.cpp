// pinstab._compiled.joint_limit_gap(s) and joint_limit_rate(s): the gaps and rates of joint-limit row blocks (kind 8,
// cpp/core_rows.hpp), of one block at one state or of many at many samples, the core's own rule (joint_limit_gap,
// joint_limit_rate) for pinstab.constraints.joint_limits (JointLimit.gap / speed, LimitWatch) and the event loop.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "core_rows.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Refuse a block that is not a joint limit or whose index lies outside a vector of `size` entries.
void check_limits(const std::vector<const RowBlock*>& blocks, Eigen::Index size, bool velocity, const char* name) {
  for (const RowBlock* block : blocks) {
    if (block->kind != RowKind::joint_limit || block->coefficients.size() != 1 || block->q_indices.size() != 1 ||
        block->v_indices.size() != 1) {
      throw std::invalid_argument(std::string(name) + ": a block that is not a joint limit (kind 8)");
    }
    const int index = velocity ? block->v_indices(0) : block->q_indices(0);
    if (index < 0 || index >= size) throw std::invalid_argument(std::string(name) + ": an index outside the state");
  }
}

}  // namespace

void bind_limits(nb::module_& m) {
  using State = Eigen::Ref<const VectorXd>;  // float64 arrays read in place (C order: no copy)
  using Samples = Eigen::Ref<const RowMatrix>;
  m.def(
      "joint_limit_gap",
      [](const RowBlock& block, State q) {
        check_limits({&block}, q.size(), false, "joint_limit_gap");
        return joint_limit_gap(block, q);
      },
      "block"_a, "q"_a, "The joint-limit block's gap sign (q_i - bound) [rad or m] (positive inside the range) at q (nq).");
  m.def(
      "joint_limit_rate",
      [](const RowBlock& block, State v) {
        check_limits({&block}, v.size(), true, "joint_limit_rate");
        return joint_limit_rate(block, v);
      },
      "block"_a, "v"_a, "The joint-limit block's G v = sign v_i [rad/s or m/s] at v (nv): of an acceleration, G a.");
  m.def(
      "joint_limit_gaps",
      [](const std::vector<const RowBlock*>& blocks, Samples qs) {
        check_limits(blocks, qs.cols(), false, "joint_limit_gaps");
        Eigen::MatrixXd gaps(qs.rows(), static_cast<Eigen::Index>(blocks.size()));
        for (Eigen::Index k = 0; k < qs.rows(); ++k) {
          for (size_t i = 0; i < blocks.size(); ++i) {
            gaps(k, static_cast<Eigen::Index>(i)) = joint_limit_gap(*blocks[i], qs.row(k).transpose());
          }
        }
        return gaps;
      },
      "blocks"_a, "qs"_a,
      "Each joint-limit block's gap sign (q_i - bound) [rad or m] (positive inside the range) at each sample: (samples, "
      "blocks) from qs (samples x nq).");
  m.def(
      "joint_limit_rates",
      [](const std::vector<const RowBlock*>& blocks, Samples vs) {
        check_limits(blocks, vs.cols(), true, "joint_limit_rates");
        Eigen::MatrixXd rates(vs.rows(), static_cast<Eigen::Index>(blocks.size()));
        for (Eigen::Index k = 0; k < vs.rows(); ++k) {
          for (size_t i = 0; i < blocks.size(); ++i) {
            rates(k, static_cast<Eigen::Index>(i)) = joint_limit_rate(*blocks[i], vs.row(k).transpose());
          }
        }
        return rates;
      },
      "blocks"_a, "vs"_a,
      "Each joint-limit block's G x = sign x_i at each row x of vs (samples x nv): the gap's rate [rad/s or m/s] of "
      "velocities, its second derivative of accelerations (the row has no drift); (samples, blocks).");
}

}  // namespace pinstab
