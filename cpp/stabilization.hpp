// The stabilization law, the one place it is written: -K rate - S phi per row (docs/mathematics.md section 3), with
// phi [m or rad] the position residual, rate = G v + g_t [m/s or rad/s], the stiffness S [1/s^2] and the velocity
// gain K [1/s] (Baumgarte's Kp and Kd; Kd / 2 on nonholonomic rows). The core's term (stabilization_term,
// cpp/core_kernel.hpp), the banded and servo kernels' right-hand sides and the native path's residual check apply it
// through this template, on a row, a vector of rows, or a point's three components (the banded kernel applies it
// per point, before the linear map to the rows: rows = S (T_b - T_a)).
#pragma once

namespace pinstab {

// -K rate - S phi [units of phi / s^2] for a scalar or an Eigen array/vector expression (velocity_gain: a scalar, or
// an array of one gain per row).
template <typename Gain, typename Rate, typename Phi>
auto stabilization_law(double stiffness, const Gain& velocity_gain, const Rate& rate, const Phi& phi) {
  return -(velocity_gain * rate) - stiffness * phi;
}

}  // namespace pinstab
