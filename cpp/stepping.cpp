#include <pinocchio/algorithm/joint-configuration.hpp>

#include "kernels.hpp"

namespace pinstab {
namespace {

// q (+) dq and the stage slopes of pinstab.integration.schemes (pinstab.model.ConstrainedModel's flat and euclidean):
// np.add where every joint has one coordinate (no model: the kernel's are so), else pinocchio::integrate; the stage
// velocity itself where every joint has one velocity coordinate, else dDifference (ARG1) applied to it.
struct Group {
  const pinocchio::Model* model;
  bool flat = true, euclidean = true;
  Eigen::MatrixXd carry;

  explicit Group(const pinocchio::Model* group) : model(group) {
    if (model == nullptr) return;
    for (int j = 1; j < model->njoints; ++j) {
      flat = flat && model->joints[j].nv() == 1;
      euclidean = euclidean && model->joints[j].nv() == 1 && model->joints[j].nq() == 1;
    }
    carry.setZero(model->nv, model->nv);  // dDifference writes the joints' diagonal blocks only
  }
  VectorXd integrate(const VectorXd& q, const VectorXd& dq) const {
    if (euclidean) return q + dq;
    VectorXd result(q.size());
    pinocchio::integrate(*model, q, dq, result);
    return result;
  }
  VectorXd slope(const VectorXd& q, const VectorXd& q_stage, const VectorXd& v_stage) {
    if (flat) return v_stage;
    pinocchio::dDifference(*model, q, q_stage, carry, pinocchio::ARG1);
    return carry * v_stage;
  }
};

}  // namespace

// The same sums, in the same order, as pinstab.integration.schemes.
int advance(Kernel& kernel, Scheme scheme, const VectorXd& q0, const VectorXd& v0, const VectorXd& tau, double dt,
            long start, int steps, RowMatrix& qs, RowMatrix& vs) {
  const int nv = kernel.nv();
  Group group(kernel.group());
  VectorXd q = q0, v = v0, a1(nv), a2(nv), a3(nv), a4(nv), q2, v2(nv), q3, v3(nv), q4, v4(nv), k2, k3;
  const double half = 0.5 * dt, sixth = dt / 6.0;
  for (int k = 0; k < steps; ++k) {
    const double t = static_cast<double>(start + k) * dt;  // Python's k * dt
    if (!kernel.acceleration(t, q, v, tau, a1)) return k;
    switch (scheme) {
      case Scheme::euler:
        q = group.integrate(q, dt * v);
        v = v + dt * a1;
        break;
      case Scheme::semi_implicit_euler:
        v = v + dt * a1;
        q = group.integrate(q, dt * v);
        break;
      case Scheme::heun:
        q2 = group.integrate(q, dt * v);
        v2 = v + dt * a1;
        if (!kernel.acceleration(t + dt, q2, v2, tau, a2)) return k;
        q = group.integrate(q, half * (v + group.slope(q, q2, v2)));
        v = v + half * (a1 + a2);
        break;
      case Scheme::rk4:
        v2 = v + half * a1;
        q2 = group.integrate(q, half * v);
        if (!kernel.acceleration(t + half, q2, v2, tau, a2)) return k;
        k2 = group.slope(q, q2, v2);
        v3 = v + half * a2;
        q3 = group.integrate(q, half * k2);
        if (!kernel.acceleration(t + half, q3, v3, tau, a3)) return k;
        k3 = group.slope(q, q3, v3);
        v4 = v + dt * a3;
        q4 = group.integrate(q, dt * k3);
        if (!kernel.acceleration(t + dt, q4, v4, tau, a4)) return k;
        q = group.integrate(q, sixth * (v + 2.0 * (k2 + k3) + group.slope(q, q4, v4)));
        v = v + sixth * (a1 + 2.0 * (a2 + a3) + a4);
        break;
    }
    qs.row(k) = q.transpose();
    vs.row(k) = v.transpose();
  }
  return steps;
}

}  // namespace pinstab
