#include "spectrum.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pinstab {

namespace {
constexpr int kMaxIterations = 12;       // Rayleigh quotient iterations (cubic: 3-4 from a warm start)
constexpr int kBisections = 200;         // at most; each halves the bracket
constexpr double kConverged = 1e-15;     // relative change of the Rayleigh quotient that ends the iterations
constexpr double kMargin = 1e-9;         // relative margin of the inertia check around an eigenvalue ...
constexpr double kFloor = 1e-13;         // ... at least this fraction of the largest eigenvalue
}  // namespace

GramSpectrum::GramSpectrum(Pattern pattern) : pattern_(std::move(pattern)) {
  const int n = pattern_.rows, b = pattern_.band;
  gram_.setZero(b + 1, n);
  work_.setZero(b + 1, n);
  lu_.setZero(3 * b + 1, n);
  transposed_.setZero(pattern_.entry_cols.size() ? pattern_.entry_cols.maxCoeff() + 1 : 0);
}

double GramSpectrum::norm_of_transpose_times(const VectorXd& values, const VectorXd& x) {
  // |G^T x| with G's entries, accumulated by column
  const VectorXi& cols = pattern_.entry_cols;
  transposed_.setZero();
  for (int e = 0; e < values.size(); ++e) transposed_(cols(e)) += values(e) * x(pattern_.entry_rows(e));
  return transposed_.norm();
}

int GramSpectrum::count_below(double shift) {
  // negative pivots of LDL^T of A - shift I (no pivoting; Sylvester's law of inertia)
  const int n = pattern_.rows, b = pattern_.band;
  work_ = gram_;
  work_.row(0).array() -= shift;
  int negative = 0;
  for (int j = 0; j < n; ++j) {
    double pivot = work_(0, j);
    if (pivot == 0.0) pivot = std::numeric_limits<double>::epsilon() * (std::abs(shift) + 1e-300);
    if (pivot < 0.0) ++negative;
    const int last = std::min(n - 1, j + b);
    for (int i = j + 1; i <= last; ++i) {  // the trailing block minus l_ij d_j l_kj
      const double lij = work_(i - j, j) / pivot;
      for (int k = i; k <= last; ++k) work_(k - i, i) -= lij * work_(k - j, j);
    }
  }
  return negative;
}

bool GramSpectrum::shifted_solve(double shift, VectorXd& x) {
  // x <- (A - shift I)^-1 x by the banded LU with partial pivoting; false when exactly singular
  const int n = pattern_.rows, b = pattern_.band;
  lu_.setZero();
  for (int j = 0; j < n; ++j) {
    for (int d = 0; d <= b && j + d < n; ++d) {
      const double value = gram_(d, j) - (d == 0 ? shift : 0.0);
      lu_(2 * b + d, j) = value;          // A(j + d, j)
      if (d > 0) lu_(2 * b - d, j + d) = value;  // A(j, j + d)
    }
  }
  return banded_solve(lu_, b, x, pivots_) == 0;
}

double GramSpectrum::bisect(int index, double upper) {
  // the index-th smallest eigenvalue (0-based) to kConverged of upper, from the inertia
  double low = 0.0, high = upper;
  for (int i = 0; i < kBisections && high - low > kConverged * upper; ++i) {
    const double middle = 0.5 * (low + high);
    if (count_below(middle) > index) {
      high = middle;
    } else {
      low = middle;
    }
  }
  return 0.5 * (low + high);
}

double GramSpectrum::singular_value(const VectorXd& values, int index, VectorXd& vector, double scale) {
  const int n = pattern_.rows;
  VectorXd x = vector;
  double rho = std::pow(norm_of_transpose_times(values, x), 2);
  bool located = false;
  for (int pass = 0; pass < 2 && !located; ++pass) {
    for (int i = 0; i < kMaxIterations; ++i) {
      VectorXd y = x;
      if (!shifted_solve(rho, y)) break;  // rho is an eigenvalue to the last bit
      const double size = y.norm();
      if (!(size > 0.0) || !std::isfinite(size)) break;
      x = y / size;
      const double next = std::pow(norm_of_transpose_times(values, x), 2);
      const bool done = std::abs(next - rho) <= kConverged * scale;
      rho = next;
      if (done) break;
    }
    const double margin = std::max(kMargin * rho, kFloor * scale);
    located = count_below(rho - margin) == index && count_below(rho + margin) > index;
    if (!located) {  // the iterations found another eigenvalue: start again next to the one sought
      rho = bisect(index, scale * (1.0 + kMargin));
      x = VectorXd::Ones(n).normalized();
      for (int i = 0; i < 3; ++i) {  // inverse iteration at the bisected shift: its eigenvector
        VectorXd y = x;
        if (!shifted_solve(rho * (1.0 + 1e-12) + kFloor * scale * 1e-3, y)) break;
        x = y.normalized();
      }
      rho = std::pow(norm_of_transpose_times(values, x), 2);
    }
  }
  vector = x;
  return std::sqrt(rho);
}

double GramSpectrum::relative(const VectorXd& values, int r) {
  const Pattern& p = pattern_;
  const int n = p.rows;
  if (r < 1 || r > n || !values.allFinite()) return std::numeric_limits<double>::quiet_NaN();
  gram_.setZero();
  double* slots = gram_.data();
  for (int k = 0; k < p.pair_slot.size(); ++k) slots[p.pair_slot(k)] += values(p.pair_first(k)) * values(p.pair_second(k));
  // a bound on the largest eigenvalue (Gershgorin) scales the tolerances
  double bound = 0.0;
  for (int j = 0; j < n; ++j) {
    double row = std::abs(gram_(0, j));
    for (int d = 1; d <= p.band; ++d) {
      if (j + d < n) row += std::abs(gram_(d, j));
      if (j - d >= 0) row += std::abs(gram_(d, j - d));
    }
    bound = std::max(bound, row);
  }
  if (!(bound > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (high_vector_.size() != n) high_vector_ = VectorXd::Ones(n).normalized();
  const int index = n - r;
  if (low_index_ != index || low_vector_.size() != n) low_vector_ = VectorXd::Ones(n).normalized(), low_index_ = index;
  const double high = singular_value(values, n - 1, high_vector_, bound);
  const double low = singular_value(values, index, low_vector_, bound);
  return high > 0.0 ? low / high : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace pinstab
