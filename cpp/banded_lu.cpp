#include <algorithm>
#include <cmath>

#include "kernels.hpp"

namespace pinstab {

int banded_solve(Eigen::Ref<Eigen::MatrixXd> ab, int band, Eigen::Ref<VectorXd> b, std::vector<int>& pivots) {
  const int n = static_cast<int>(ab.cols());
  const int kl = band, ku = band, kv = ku + kl;
  pivots.assign(n, 0);
  int info = 0, ju = 0;
  for (int j = 0; j < n; ++j) {  // dgbtf2 (fill-in rows start at zero: the caller zeroes ab)
    const int km = std::min(kl, n - 1 - j);
    int jp = 0;
    double largest = std::abs(ab(kv, j));
    for (int i = 1; i <= km; ++i) {
      if (std::abs(ab(kv + i, j)) > largest) largest = std::abs(ab(kv + i, j)), jp = i;
    }
    pivots[j] = j + jp;
    if (ab(kv + jp, j) == 0.0) {
      if (info == 0) info = j + 1;
      continue;
    }
    ju = std::max(ju, std::min(j + ku + jp, n - 1));
    if (jp != 0) {
      for (int c = j; c <= ju; ++c) std::swap(ab(kv + jp - (c - j), c), ab(kv - (c - j), c));
    }
    if (km > 0) {
      const double inverse = 1.0 / ab(kv, j);
      for (int i = 1; i <= km; ++i) ab(kv + i, j) *= inverse;
      for (int c = j + 1; c <= ju; ++c) {
        const double pivot_row = ab(kv - (c - j), c);
        if (pivot_row != 0.0) {
          for (int i = 1; i <= km; ++i) ab(kv + i - (c - j), c) -= ab(kv + i, j) * pivot_row;
        }
      }
    }
  }
  if (info != 0) return info;
  for (int j = 0; j < n - 1; ++j) {  // dgbtrs: L, row interchanges as they were made
    const int lm = std::min(kl, n - 1 - j);
    const int l = pivots[j];
    if (l != j) std::swap(b(l), b(j));
    const double value = b(j);
    for (int i = 1; i <= lm; ++i) b(j + i) -= ab(kv + i, j) * value;
  }
  for (int j = n - 1; j >= 0; --j) {  // U, bandwidth kv (dtbsv)
    if (b(j) != 0.0) {
      b(j) /= ab(kv, j);
      const double value = b(j);
      for (int i = std::max(0, j - kv); i < j; ++i) b(i) -= value * ab(kv + i - j, j);
    }
  }
  return 0;
}

}  // namespace pinstab
