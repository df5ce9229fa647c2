// Targets c(t) of prescribed rows, compiled (pinstab.constraints.targets' trajectories, one component each).
#pragma once

#include <vector>

#include <Eigen/Core>

namespace pinstab {

// Either offset + amplitude sin(omega t + phase), or a piecewise polynomial: on piece i (breaks[i] <= t <
// breaks[i + 1]) sum_k coefficients(i, k) x^k, x = (t - origins[i]) / scale (scale [s]: the coefficients' unit of
// time, a move's duration: its shape's coefficients stay of order one, and its derivatives round as the closed
// form's); held (zero derivatives) at its end values outside [breaks[0], breaks[last]] when `held`, else the first
// or last piece extended.
struct Target {
  bool sinusoid = true;
  double offset = 0.0, amplitude = 0.0, omega = 0.0, phase = 0.0;
  Eigen::VectorXd breaks, origins;
  Eigen::MatrixXd coefficients;  // (pieces, degree + 1), ascending powers
  double scale = 1.0;
  bool held = false;

  // (c, dc/dt, d2c/dt2) at t [s]
  void evaluate(double t, double& value, double& rate, double& curvature) const;
};

// A target of several components, one Target each (pinstab.constraints.targets.TargetTrajectory.evaluate calls it).
struct Targets {
  std::vector<Target> components;

  // (c, dc/dt, d2c/dt2) of every component at t [s], each of components.size()
  void evaluate(double t, Eigen::VectorXd& value, Eigen::VectorXd& rate, Eigen::VectorXd& curvature) const;
};

}  // namespace pinstab
