// Kernel::jacobian's default: forward differences of the kernel's own acceleration on the configuration group.
//
// Column j of dadq is (a(q (+) d_j e_j, v) - a(q, v)) / d_j, column j of dadv (a(q, v + d_j e_j) - a(q, v)) / d_j,
// with d_j = sqrt(eps) max(1, |x_j|) (x_j: the coordinate's size, |neutral (-) q| for a position, |v_j| for a
// velocity): 2 nv + 1 evaluations. The error of an entry is the truncation d_j |d2a/dx_j2| / 2 plus the rounding
// ~2 eps |a| / d_j, both of order sqrt(eps) ~ 1.5e-8 relative to the scales of a and x: ample for the iteration
// matrix of a simplified Newton iteration, whose answer does not depend on it (only its rate of convergence does).
// Central differences would give ~eps^(2/3) at 4 nv evaluations; Newton gains nothing from them.
#include <cmath>
#include <limits>

#include "adaptive.hpp"

namespace pinstab {

bool Kernel::jacobian(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                      Eigen::MatrixXd& dadq, Eigen::MatrixXd& dadv) {
  const int n = nv();
  const Group group(this->group());
  const double root = std::sqrt(std::numeric_limits<double>::epsilon());
  VectorXd base(n), shifted(n), dq = VectorXd::Zero(n), v_shifted = v;
  if (!acceleration(stage, t, q, v, tau, base)) return false;
  const VectorXd size = magnitude(group, q);
  dadq.resize(n, n);
  dadv.resize(n, n);
  for (int j = 0; j < n; ++j) {
    const double step = root * std::max(1.0, size(j));
    dq(j) = step;
    if (!acceleration(stage, t, group.integrate(q, dq), v, tau, shifted)) return false;
    dadq.col(j) = (shifted - base) / step;
    dq(j) = 0.0;
  }
  for (int j = 0; j < n; ++j) {
    const double step = root * std::max(1.0, std::abs(v(j)));
    v_shifted(j) = v(j) + step;
    if (!acceleration(stage, t, q, v_shifted, tau, shifted)) return false;
    dadv.col(j) = (shifted - base) / (v_shifted(j) - v(j));  // the step as represented
    v_shifted(j) = v(j);
  }
  return true;
}

}  // namespace pinstab
