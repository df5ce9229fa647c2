// The numerical rank of a matrix from its singular values, the one rule of the servo's realizability test
// (cpp/servo_kernel.hpp) and the grasp hold's least-squares forces (cpp/grasp_forces.hpp): a singular value counts when
// it lies above tolerance times max(1, the largest), 1 being the scale of the unit-free matrices they judge (cosines,
// and forces against a load in their own units).
#pragma once

#include <algorithm>

#include <Eigen/Core>

namespace pinstab {

// The floor a singular value must exceed to count: tolerance max(1, the largest) (singular values descending; none:
// the tolerance itself).
inline double rank_floor(const Eigen::VectorXd& singular_values, double tolerance) {
  return tolerance * std::max(singular_values.size() ? singular_values(0) : 0.0, 1.0);
}

}  // namespace pinstab
