// The configuration group the explicit schemes step on (pinstab.model.ConstrainedModel's flat and euclidean).
#pragma once

#include <pinocchio/algorithm/joint-configuration.hpp>

#include "kernels.hpp"

namespace pinstab {

// q (+) dq and the stage slopes: q + dq where every joint has one coordinate (no model: the kernel's are so), else
// pinocchio::integrate; the stage velocity itself where every joint has one velocity coordinate, else dDifference
// (ARG1) applied to it (carried to the tangent space at the step's start, Runge-Kutta-Munthe-Kaas).
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

// Central differences of f over the configuration group: column k of jacobian (nv x nv) is
// (f(q (+) step e_k) - f(q (+) -step e_k)) / (2 step), q (+) dq by pinocchio::integrate (dq in the tangent space at q),
// f(q, value) filling value (nv) and returning false where it is not to be used; false then (jacobian incomplete).
template <typename Function>
bool tangent_differences(const pinocchio::Model& model, const VectorXd& q, double step, Function&& f,
                         Eigen::MatrixXd& jacobian) {
  jacobian.resize(model.nv, model.nv);
  VectorXd shifted(model.nq), plus(model.nv), minus(model.nv), dq = VectorXd::Zero(model.nv);
  for (int k = 0; k < model.nv; ++k) {
    dq(k) = step;
    pinocchio::integrate(model, q, dq, shifted);
    if (!f(shifted, plus)) return false;
    dq(k) = -step;
    pinocchio::integrate(model, q, dq, shifted);
    if (!f(shifted, minus)) return false;
    dq(k) = 0.0;
    jacobian.col(k) = (plus - minus) / (2.0 * step);
  }
  return true;
}

// One step of a fixed scheme (Scheme) with its stages' storage.
class SchemeStep {
 public:
  SchemeStep(Scheme scheme, const pinocchio::Model* group) : scheme_(scheme), group_(group) {}
  // One step of dt [s] from (q, v) at t [s] under tau: q, v become the end state. False (q, v unchanged) when an
  // evaluation (stage i at its node, kernel.acceleration(i, ...)) is not to be used.
  bool take(Kernel& kernel, const VectorXd& tau, double t, double dt, VectorXd& q, VectorXd& v);

 private:
  Scheme scheme_;
  Group group_;
  VectorXd a1_, a2_, a3_, a4_, q2_, v2_, q3_, v3_, q4_, v4_, k2_, k3_;
};

}  // namespace pinstab
