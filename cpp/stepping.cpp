#include "group.hpp"
#include "step_loop.hpp"

namespace pinstab {

// The schemes of pinstab.integration.schemes (Euler, SemiImplicitEuler, Heun, RK4): the only place their sums are.
bool SchemeStep::take(Kernel& kernel, const VectorXd& tau, double t, double dt, VectorXd& q, VectorXd& v) {
  const Eigen::Index nv = v.size();
  a1_.resize(nv), a2_.resize(nv), a3_.resize(nv), a4_.resize(nv);
  const double half = 0.5 * dt, sixth = dt / 6.0;
  if (!kernel.acceleration(0, t, q, v, tau, a1_)) return false;
  switch (scheme_) {
    case Scheme::euler:
      q = group_.integrate(q, dt * v);
      v = v + dt * a1_;
      break;
    case Scheme::semi_implicit_euler:
      v = v + dt * a1_;
      q = group_.integrate(q, dt * v);
      break;
    case Scheme::heun:
      q2_ = group_.integrate(q, dt * v);
      v2_ = v + dt * a1_;
      if (!kernel.acceleration(1, t + dt, q2_, v2_, tau, a2_)) return false;
      q = group_.integrate(q, half * (v + group_.slope(q, q2_, v2_)));
      v = v + half * (a1_ + a2_);
      break;
    case Scheme::rk4:
      v2_ = v + half * a1_;
      q2_ = group_.integrate(q, half * v);
      if (!kernel.acceleration(1, t + half, q2_, v2_, tau, a2_)) return false;
      k2_ = group_.slope(q, q2_, v2_);
      v3_ = v + half * a2_;
      q3_ = group_.integrate(q, half * k2_);
      if (!kernel.acceleration(2, t + half, q3_, v3_, tau, a3_)) return false;
      k3_ = group_.slope(q, q3_, v3_);
      v4_ = v + dt * a3_;
      q4_ = group_.integrate(q, dt * k3_);
      if (!kernel.acceleration(3, t + dt, q4_, v4_, tau, a4_)) return false;
      q = group_.integrate(q, sixth * (v + 2.0 * (k2_ + k3_) + group_.slope(q, q4_, v4_)));
      v = v + sixth * (a1_ + 2.0 * (a2_ + a3_) + a4_);
      break;
  }
  return true;
}

int advance(Kernel& kernel, Scheme scheme, const VectorXd& q0, const VectorXd& v0, const VectorXd& tau, double dt,
            long start, int steps, RowMatrix& qs, RowMatrix& vs, Correction* correction) {
  SchemeStep step(scheme, kernel.group());
  auto take = [&](double t, VectorXd& q, VectorXd& v) { return step.take(kernel, tau, t, dt, q, v); };
  return fixed_steps(take, q0, v0, dt, start, steps, qs, vs, correction);
}

}  // namespace pinstab
