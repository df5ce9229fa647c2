#include <algorithm>
#include <cmath>

#include "kernels.hpp"

namespace pinstab {

int banded_solve(Eigen::Ref<Eigen::MatrixXd> ab, int band, Eigen::Ref<VectorXd> b, std::vector<int>& pivots) {
  const int n = static_cast<int>(ab.cols());
  const int kl = band, ku = band, kv = ku + kl;
  const Eigen::Index ld = ab.outerStride();
  double* const a = ab.data();  // A(i, j) of the band at a[j * ld + kv + i - j]
  double* const x = b.data();
  pivots.assign(n, 0);
  int info = 0, ju = 0;
  for (int j = 0; j < n; ++j) {  // dgbtf2 (fill-in rows start at zero: the caller zeroes ab)
    double* const column = a + j * ld + kv;  // column[i] = A(j + i, j)
    const int km = std::min(kl, n - 1 - j);
    int jp = 0;
    double largest = std::abs(column[0]);
    for (int i = 1; i <= km; ++i) {
      if (std::abs(column[i]) > largest) largest = std::abs(column[i]), jp = i;
    }
    pivots[j] = j + jp;
    if (column[jp] == 0.0) {
      if (info == 0) info = j + 1;
      continue;
    }
    ju = std::max(ju, std::min(j + ku + jp, n - 1));
    if (jp != 0) {  // swap rows j and j + jp in columns j .. ju
      for (int c = j; c <= ju; ++c) {
        double* const target = a + c * ld + kv - (c - j);  // target[i] = A(j + i, c)
        std::swap(target[jp], target[0]);
      }
    }
    if (km > 0) {
      const double inverse = 1.0 / column[0];
      for (int i = 1; i <= km; ++i) column[i] *= inverse;
      for (int c = j + 1; c <= ju; ++c) {  // A(j + i, c) -= l(j + i) A(j, c)
        double* const target = a + c * ld + kv - (c - j);
        const double pivot_row = target[0];
        if (pivot_row != 0.0) {
          for (int i = 1; i <= km; ++i) target[i] -= column[i] * pivot_row;
        }
      }
    }
  }
  if (info != 0) return info;
  for (int j = 0; j < n - 1; ++j) {  // dgbtrs: L, row interchanges as they were made
    const double* const column = a + j * ld + kv;
    const int lm = std::min(kl, n - 1 - j);
    const int l = pivots[j];
    if (l != j) std::swap(x[l], x[j]);
    const double value = x[j];
    for (int i = 1; i <= lm; ++i) x[j + i] -= column[i] * value;
  }
  for (int j = n - 1; j >= 0; --j) {  // U, bandwidth kv (dtbsv)
    if (x[j] != 0.0) {
      const double* const column = a + j * ld + kv;  // column[i - j] = A(i, j), i <= j
      x[j] /= column[0];
      const double value = x[j];
      for (int i = std::max(0, j - kv); i < j; ++i) x[i] -= value * column[i - j];
    }
  }
  return 0;
}

}  // namespace pinstab
