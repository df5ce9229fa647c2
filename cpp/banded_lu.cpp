#include <algorithm>
#include <cmath>

#include "kernels.hpp"

namespace pinstab {

int banded_factor(Eigen::Ref<Eigen::MatrixXd> ab, int band, std::vector<int>& pivots) {
  const int n = static_cast<int>(ab.cols());
  const int kl = band, ku = band, kv = ku + kl;
  const Eigen::Index ld = ab.outerStride();
  double* const a = ab.data();  // A(i, j) of the band at a[j * ld + kv + i - j]
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
  return info;
}

void banded_substitute(const Eigen::Ref<const Eigen::MatrixXd>& ab, int band, const std::vector<int>& pivots,
                       Eigen::Ref<VectorXd> b) {
  const int n = static_cast<int>(ab.cols());
  const int kl = band, kv = 2 * band;
  const Eigen::Index ld = ab.outerStride();
  const double* const a = ab.data();
  double* const x = b.data();
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
}

int banded_solve(Eigen::Ref<Eigen::MatrixXd> ab, int band, Eigen::Ref<VectorXd> b, std::vector<int>& pivots) {
  const int info = banded_factor(ab, band, pivots);
  if (info == 0) banded_substitute(ab, band, pivots, b);
  return info;
}

void banded_residual(const Eigen::Ref<const Eigen::MatrixXd>& ab, int band, const VectorXd& x, const VectorXd& b,
                     VectorXd& residual) {
  const int n = static_cast<int>(ab.cols());
  const int kv = 2 * band;
  std::vector<long double> sum(b.data(), b.data() + n);
  for (int j = 0; j < n; ++j) {
    const double* const column = ab.data() + j * ab.outerStride() + kv - j;  // column[i] = A(i, j)
    const long double value = x[j];
    for (int i = std::max(0, j - band); i <= std::min(n - 1, j + band); ++i) sum[i] -= column[i] * value;
  }
  for (int i = 0; i < n; ++i) residual[i] = static_cast<double>(sum[i]);
}

}  // namespace pinstab
