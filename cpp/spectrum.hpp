#pragma once

#include "kernels.hpp"

namespace pinstab {

// Singular values of a sparse constraint Jacobian G (rows x nv, a fixed pattern) from the banded Gram matrix
// G G^T: shift-invert Rayleigh quotient iterations warm-started from the last call's vectors, each result
// checked by Sylvester's inertia (negative pivots of LDL^T) and found by bisection on it when the check fails.
// A singular value is read as |G^T x| from its Gram eigenvector x: accurate to rounding of sigma_1, as an SVD's.
class GramSpectrum {
 public:
  struct Pattern {
    VectorXi entry_rows;    // each entry's row, in the Gram's band order
    VectorXi entry_cols;    // each entry's column
    VectorXi pair_first, pair_second, pair_slot;  // products of entries sharing a column, and their Gram slots
    int rows = 0, band = 0;
  };

  explicit GramSpectrum(Pattern pattern);
  // sigma_r / sigma_1 of G with entries `values` (r: 1-based rank of the singular value, r <= rows).
  double relative(const VectorXd& values, int r);

 private:
  double singular_value(const VectorXd& values, int index, VectorXd& vector, double scale);
  double norm_of_transpose_times(const VectorXd& values, const VectorXd& x);
  int count_below(double shift);
  bool shifted_solve(double shift, VectorXd& x);
  double bisect(int index, double upper);

  Pattern pattern_;
  Eigen::MatrixXd gram_;  // lower band storage: gram_(d, j) = A(j + d, j)
  Eigen::MatrixXd work_, lu_;
  VectorXd transposed_;  // G^T x
  VectorXd low_vector_, high_vector_;
  int low_index_ = -1;
  std::vector<int> pivots_;
};

}  // namespace pinstab
