#include "targets.hpp"

#include <algorithm>
#include <cmath>

namespace pinstab {

void Target::evaluate(double t, double& value, double& rate, double& curvature) const {
  if (sinusoid) {
    const double angle = omega * t + phase, wave = amplitude * std::sin(angle);
    value = offset + wave;
    rate = amplitude * omega * std::cos(angle);
    curvature = -(omega * omega) * wave;
    return;
  }
  const int pieces = static_cast<int>(coefficients.rows()), last = static_cast<int>(breaks.size()) - 1;
  bool hold = false;
  if (held && (t < breaks(0) || t > breaks(last))) {
    hold = true;
    t = t < breaks(0) ? breaks(0) : breaks(last);
  }
  const double* end = breaks.data() + last;
  const int piece = std::clamp(static_cast<int>(std::upper_bound(breaks.data() + 1, end, t) - breaks.data()) - 1, 0,
                               pieces - 1);
  const double x = (t - origins(piece)) / scale;
  value = rate = curvature = 0.0;
  for (int k = static_cast<int>(coefficients.cols()) - 1; k >= 0; --k) {  // Horner, with the two derivatives
    curvature = curvature * x + 2.0 * rate;
    rate = rate * x + value;
    value = value * x + coefficients(piece, k);
  }
  if (hold) {
    rate = curvature = 0.0;
  } else {
    rate /= scale;
    curvature /= scale * scale;
  }
}

void Targets::evaluate(double t, Eigen::VectorXd& value, Eigen::VectorXd& rate, Eigen::VectorXd& curvature) const {
  const Eigen::Index size = static_cast<Eigen::Index>(components.size());
  value.resize(size), rate.resize(size), curvature.resize(size);
  for (Eigen::Index i = 0; i < size; ++i) components[i].evaluate(t, value(i), rate(i), curvature(i));
}

}  // namespace pinstab
