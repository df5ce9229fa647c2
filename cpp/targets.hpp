// Targets c(t) of prescribed rows, compiled (pinstab.constraints.targets' trajectories, one component each).
#pragma once

#include <Eigen/Core>

namespace pinstab {

// Either offset + amplitude sin(omega t + phase), or a piecewise polynomial: on piece i (breaks[i] <= t <
// breaks[i + 1]) sum_k coefficients(i, k) (t - origins[i])^k; held (zero derivatives) at its end values outside
// [breaks[0], breaks[last]] when `held`, else the first or last piece extended.
struct Target {
  bool sinusoid = true;
  double offset = 0.0, amplitude = 0.0, omega = 0.0, phase = 0.0;
  Eigen::VectorXd breaks, origins;
  Eigen::MatrixXd coefficients;  // (pieces, degree + 1), ascending powers
  bool held = false;

  // (c, dc/dt, d2c/dt2) at t [s]
  void evaluate(double t, double& value, double& rate, double& curvature) const;
};

}  // namespace pinstab
