#include "kernels.hpp"

namespace pinstab {

// The same sums, in the same order, as pinstab.integration.schemes (np.add for q (+) dq).
int advance(Kernel& kernel, Scheme scheme, const VectorXd& q0, const VectorXd& v0, const VectorXd& tau, double dt,
            long start, int steps, RowMatrix& qs, RowMatrix& vs) {
  const int nv = kernel.nv();
  VectorXd q = q0, v = v0, a1(nv), a2(nv), a3(nv), a4(nv), q2(nv), v2(nv), q3(nv), v3(nv), q4(nv), v4(nv);
  const double half = 0.5 * dt, sixth = dt / 6.0;
  for (int k = 0; k < steps; ++k) {
    const double t = static_cast<double>(start + k) * dt;  // Python's k * dt
    if (!kernel.acceleration(t, q, v, tau, a1)) return k;
    switch (scheme) {
      case Scheme::euler:
        q = q + dt * v;
        v = v + dt * a1;
        break;
      case Scheme::semi_implicit_euler:
        v = v + dt * a1;
        q = q + dt * v;
        break;
      case Scheme::heun:
        q2 = q + dt * v;
        v2 = v + dt * a1;
        if (!kernel.acceleration(t + dt, q2, v2, tau, a2)) return k;
        q = q + half * (v + v2);
        v = v + half * (a1 + a2);
        break;
      case Scheme::rk4:
        v2 = v + half * a1;
        q2 = q + half * v;
        if (!kernel.acceleration(t + half, q2, v2, tau, a2)) return k;
        v3 = v + half * a2;
        q3 = q + half * v2;
        if (!kernel.acceleration(t + half, q3, v3, tau, a3)) return k;
        v4 = v + dt * a3;
        q4 = q + dt * v3;
        if (!kernel.acceleration(t + dt, q4, v4, tau, a4)) return k;
        q = q + sixth * (v + 2.0 * (v2 + v3) + v4);
        v = v + sixth * (a1 + 2.0 * (a2 + a3) + a4);
        break;
    }
    qs.row(k) = q.transpose();
    vs.row(k) = v.transpose();
  }
  return steps;
}

}  // namespace pinstab
