// pinstab.paths.servo.ServoDynamics compiled: prescribed joint relations realized by controls (docs/mathematics.md section 5).
#pragma once

#include <optional>
#include <utility>

#include <Eigen/Cholesky>

#include "kernels.hpp"
#include "kkt_solve.hpp"
#include "targets.hpp"

namespace pinstab {

// Whether the controls reach every prescribed row at a state, judged free of the units of each row and each control
// (pinstab.servo.ServoSolver and ServoKernel alike). `unit` is the decoupling matrix D = S N B (p x k) with D_ij
// divided by |S_i| |N b_j|: the cosine between prescribed row i and the motion control j allows (0 where a control
// moves nothing), unchanged when a row or a control (a column of B) is scaled. `rank` counts its singular values
// above rank_tolerance times max(1, the largest) (1: the cosines' own scale); `sign` is the sign of its determinant
// when it is square (the sign of det D), else 0. `crossed`: D square of full rank whose sign differs from `last_sign`,
// the sign at the last usable evaluation (none: nothing to compare): D was singular in between, where a step may have
// passed it by. `usable`: full row rank and not crossed; only a usable evaluation's sign is the next one's last_sign
// (a refused state is no reference: a retry or the general solve compares with the last usable one).
struct Realizability {
  Eigen::MatrixXd unit;
  int rank = 0;
  double sign = 0.0;
  bool crossed = false;
  bool usable = false;
};
// decoupling: D (p x k); rows: S (p x nv); moved: N B (nv x k); last_sign: +-1 of the last usable square evaluation
Realizability realizability(const Eigen::MatrixXd& decoupling, const Eigen::MatrixXd& rows, const Eigen::MatrixXd& moved,
                            double rank_tolerance, std::optional<double> last_sign);
// Whether every control u_j lies in [lower_j, upper_j] (an infinite bound: none on that side); a NaN control lies in
// no bounds (refused: the caller says why). u, lower, upper [N m or N] (k).
bool controls_within(const VectorXd& controls, const VectorXd& lower, const VectorXd& upper);
// The least-norm u with D u = demand for a D of full row rank (p <= k), from a Householder QR of D^T: no cutoff drops
// the direction of a control whose column of D is much smaller than another's.
VectorXd least_norm(const Eigen::MatrixXd& decoupling, const VectorXd& demand);

// The solve of docs/mathematics.md section 5 up to the controls (pinstab.servo.ServoSolver and ServoKernel alike):
// with real rows G (reactions lambda; r of them, r = 0: none) and prescribed rows S (p) realized by the controls u of
// M a - G^T lambda - B u = f, G a = rhs_G, S a = rhs_S, the real rows alone give a = base + moved u with
// base = M^-1 (f + G^T lambda0), lambda0 = (G M^-1 G^T)^+ (rhs_G - G M^-1 f) and moved = N B,
// N = M^-1 - M^-1 G^T (G M^-1 G^T)^+ G M^-1 (the core solve's pseudo-inverse, DelassusPseudoInverse, with cutoff
// PSEUDO_INVERSE_CUTOFF: numpy.linalg.pinv's default rule); the prescribed rows then ask D u = demand of D = S N B,
// demand = rhs_S - S base.
constexpr double PSEUDO_INVERSE_CUTOFF = 1e-12;  // of the largest eigenvalue of G M^-1 G^T

struct ServoParts {
  VectorXd base, base_multipliers, demand;  // [m/s^2, rad/s^2] (nv), [N, N m] (r), S's units / s^2 (p)
  Eigen::MatrixXd moved, decoupling;        // N B (nv x k), D (p x k)
  Eigen::MatrixXd spread, reach;            // M^-1 G^T (nv x r), G M^-1 B (r x k)
  DelassusPseudoInverse delassus;           // (G M^-1 G^T)^+

  // From the factor of M (nv x nv), f [N, N m] (nv), G (r x nv), S (p x nv), B (nv x k), rhs_G (r), rhs_S (p).
  void compute(const Eigen::LLT<Eigen::MatrixXd>& mass, const VectorXd& force, const Eigen::MatrixXd& real,
               const Eigen::MatrixXd& prescribed, const Eigen::MatrixXd& actuation, const VectorXd& real_rhs,
               const VectorXd& prescribed_rhs);
  // a = base + moved u (nv) and, on the real rows, lambda = lambda0 - (G M^-1 G^T)^+ G M^-1 B u (r) for controls u (k)
  void finish(const VectorXd& controls, VectorXd& a, VectorXd& multipliers) const;
};

// The rows S a = c'' - Kd (S v - c') - Kp (S q - c) realized by the controls u of M a + h = tau + B u: with
// a0 = M^-1 (tau - h) and D = S M^-1 B, u is the least-norm solution of D u = rhs - S a0 and a = a0 + M^-1 B u
// (ServoParts without real rows).
// An evaluation is not to be used (false) where D is not usable (realizability: rank lost, or its determinant changed
// sign since the last usable evaluation), where a control leaves its bounds or is NaN (controls_within) or the result
// is not finite: the caller's general solve then says why or takes the limits.
class ServoKernel : public Kernel {
 public:
  // rows: S over the velocity coordinates (p x nv); position_rows: the same rows over the configuration's (p x nq)
  ServoKernel(const pinocchio::Model& model, Eigen::MatrixXd rows, Eigen::MatrixXd position_rows,
              Eigen::MatrixXd actuation, VectorXd lower,
              VectorXd upper, std::vector<Target> targets, double kp, double kd, double rank_tolerance);
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                    VectorXd& a) override;
  int nv() const override { return model_.nv; }
  // (time [s], sign of det D) of the last evaluation whose square D was usable (realizability), if any
  std::optional<std::pair<double, double>> last_sign() const { return last_sign_; }

 private:
  pinocchio::Model model_;
  pinocchio::Data data_;
  Eigen::MatrixXd rows_, position_rows_, actuation_, no_rows_;
  VectorXd lower_, upper_, controls_, rhs_, no_multipliers_;
  ServoParts parts_;
  std::vector<Target> targets_;
  double kp_, kd_, rank_tolerance_;
  Eigen::LLT<Eigen::MatrixXd> mass_;
  std::optional<std::pair<double, double>> last_sign_;
};

}  // namespace pinstab
