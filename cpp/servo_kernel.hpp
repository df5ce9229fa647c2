// pinstab.paths.servo.ServoDynamics compiled: prescribed joint relations realized by controls (docs/mathematics.md section 5).
#pragma once

#include <optional>
#include <utility>

#include <Eigen/Cholesky>

#include "kernels.hpp"
#include "targets.hpp"

namespace pinstab {

// Whether the controls reach every prescribed row at a state, judged free of the units of each row and each control
// (pinstab.servo.ServoSolver and ServoKernel alike). `unit` is the decoupling matrix D = S N B (p x k) with D_ij
// divided by |S_i| |N b_j|: the cosine between prescribed row i and the motion control j allows (0 where a control
// moves nothing), unchanged when a row or a control (a column of B) is scaled. `rank` counts its singular values
// above rank_tolerance times max(1, the largest) (1: the cosines' own scale); `sign` is the sign of its determinant
// when it is square (the sign of det D), else 0.
struct Realizability {
  Eigen::MatrixXd unit;
  int rank = 0;
  double sign = 0.0;
};
// decoupling: D (p x k); rows: S (p x nv); moved: N B (nv x k)
Realizability realizability(const Eigen::MatrixXd& decoupling, const Eigen::MatrixXd& rows, const Eigen::MatrixXd& moved,
                            double rank_tolerance);
// The least-norm u with D u = demand for a D of full row rank (p <= k), from a Householder QR of D^T: no cutoff drops
// the direction of a control whose column of D is much smaller than another's.
VectorXd least_norm(const Eigen::MatrixXd& decoupling, const VectorXd& demand);

// The rows S a = c'' - Kd (S v - c') - Kp (S q - c) realized by the controls u of M a + h = tau + B u: with
// a0 = M^-1 (tau - h) and D = S M^-1 B, u is the least-norm solution of D u = rhs - S a0 and a = a0 + M^-1 B u.
// An evaluation is not to be used (false) where D loses rank (realizability), where its determinant (square D) changed sign since the last evaluation, where a control
// leaves its bounds or the result is not finite: the caller's general solve then says why or takes the limits.
class ServoKernel : public Kernel {
 public:
  // rows: S over the velocity coordinates (p x nv); position_rows: the same rows over the configuration's (p x nq)
  ServoKernel(const pinocchio::Model& model, Eigen::MatrixXd rows, Eigen::MatrixXd position_rows,
              Eigen::MatrixXd actuation, VectorXd lower,
              VectorXd upper, std::vector<Target> targets, double kp, double kd, double rank_tolerance);
  bool acceleration(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) override;
  int nv() const override { return model_.nv; }
  // (time [s], sign of det D) of the last usable evaluation with a square D, if any
  std::optional<std::pair<double, double>> last_sign() const { return last_sign_; }

 private:
  pinocchio::Model model_;
  pinocchio::Data data_;
  Eigen::MatrixXd rows_, position_rows_, actuation_, moved_, decoupling_;
  VectorXd lower_, upper_, controls_, free_, demand_;
  std::vector<Target> targets_;
  double kp_, kd_, rank_tolerance_;
  bool limited_;
  Eigen::LLT<Eigen::MatrixXd> mass_;
  std::optional<std::pair<double, double>> last_sign_;
};

}  // namespace pinstab
