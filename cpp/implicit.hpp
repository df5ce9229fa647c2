// One step of a diagonally implicit Runge-Kutta tableau (a_ij lower triangular, an explicit first stage, a non-zero
// diagonal below it) on the configuration group, its stages solved by Newton's iteration: the only place the implicit
// schemes' arithmetic is (pinstab.integration.implicit names them). The fixed-step loop (advance_tableau), the
// error-controlled loop (attempt, adaptive_advance) and the Python step path (the bindings' one step) all take this
// step, so they take the same steps to the last bit.
//
// Stage i (i >= 1) solves, in the tangent space at the step's start (q0, v0), for its increment Z = (Zq, Zv):
//   Z = S_i + h g F(Z),  S_i = h sum_{j<i} a_ij k_j,  g = a_ii,
//   F(Z) = (slope(q0, q0 (+) Zq, v0 + Zv), a(t + c_i h, q0 (+) Zq, v0 + Zv)),
// then k_i = (Z - S_i) / (h g) (the slope the stage equation gives, not a further evaluation). The iteration matrix
// I - h g J with J = [[0, I], [dadq, dadv]] (the kernel's Jacobian) reduces by its 2 x 2 block structure to the
// nv x nv M = I - h g dadv - (h g)^2 dadq: dZv = M^-1 (r_v + h g dadq r_q), dZq = r_q + h g dZv
// (r = S_i + h g F(Z) - Z), from the guess Z = S_i + h g (I - h g J)^-1 k_(i-1) for the first two implicit stages
// and, for the later ones, the quadratic in c through Z(0) = 0 and the last two stages' increments.
//
// First a simplified Newton iteration: M's LU factors serve every stage of the same h g, the iterations and the
// steps that follow; the Jacobian (at a step's start) is kept while the iteration converges fast (rate theta <= 0.1)
// and refreshed at the next step's start after a slower one. When at the rate seen the iterations left cannot
// converge (or it diverges), a globalized iteration takes over: a continuation in the share s of the stage,
// Z(s) = s S_i + s h g F(Z(s)) from Z(0) = 0 to s = 1 (the first try s = 1 at once, from the stage's guess), each
// share solved by Newton's iteration with a Jacobian at every iterate from a linear extrapolation of the last two
// solutions, the advance of s halved when it does not contract and doubled after it does. It follows the root the
// motion takes: a large step's stage equation has others, stiff-fourbar's angles adding whole turns in one step (a
// root with velocities of 3000 rad/s beside the one at 7 rad/s), on which Newton steps from a diverged iterate land.
#pragma once

#include <Eigen/LU>

#include <memory>
#include <stdexcept>
#include <string>

#include "adaptive.hpp"

namespace pinstab {

// When Newton's iteration stops: the increment's norm (scaled per coordinate by atol + rtol |y0|, the start's sizes)
// times rate / (1 - rate) (the distance left to the solution, Hairer and Wanner's estimate; the rate the last two
// increments' ratio, at least 0.3 times the one before, 1 before the first ratio; at the first iteration the last
// stage's estimate) at most kappa; it hands over to the globalized iteration on a rate >= 1, when at the rate seen
// the iterations left of max_iterations cannot reach kappa, or after max_iterations iterations. The globalized
// iteration solves each share to kappa, and gives up after GLOBAL_ITERATIONS Jacobians or when the share's advance
// falls below MIN_SHARE (the root turns back: no solution on the motion's branch at this step).
struct NewtonSettings {
  double rtol, atol, kappa;
  int max_iterations;
};

// What Newton's iteration did over the steps: iterations (one evaluation each), Jacobians evaluated, LU
// factorizations of M, failures (a stage not solved: the step not taken), globalized iterations (Newton's with a
// Jacobian at the iterate) and continuation shares (the shares s < 1 solved on the way to s = 1).
struct NewtonCounts {
  long iterations = 0, jacobians = 0, factorizations = 0, failures = 0, globalized = 0, continuation = 0;
};

// A step whose stage could not be solved even by the globalized iteration (pinstab._compiled.NewtonFailure; the
// Python step raises pinstab.errors.NewtonError from it).
class NewtonFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ImplicitTrial : public Trial {
 public:
  ImplicitTrial(const Pair& pair, int nv, const pinocchio::Model* group, const NewtonSettings& settings);
  // Trial::take, the stages solved; with a stiffly accurate tableau the new point's slope is the last stage's
  // (has_end). False with unconverged when a stage was not solved (failed_stage, residual: the last scaled increment
  // norm, failed_iterations: its evaluations).
  bool take(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, const VectorXd& a, double t,
            double h, bool with_end) override;
  // Why the last take was not solved, for the step from t [s] of h [s].
  std::string failure(double t, double h) const;

  NewtonCounts counts;
  int failed_stage = -1, failed_iterations = 0;
  double residual = 0.0;

 private:
  enum class Solve { converged, unusable, unconverged };
  Solve stage(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t, double h, int i);
  // The globalized iteration of stage i (module comment), its solution in z_.
  Solve globalize(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t_stage,
                  double hg, double kappa, int i);
  // residual_ = share S_i + hg F(z) - z (hg: the share's): one evaluation of the dynamics (false: not usable).
  bool evaluate(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t_stage,
                double share, double hg, int i, const VectorXd& z);
  // The largest |x_c| / scale_c (NaN when one is).
  double scaled_norm(const VectorXd& x) const;
  // Stage i's increment at the step's share `share` [-] (shg = share h g [s]) carried through the linearized stage,
  // share S_i + shg (I - shg J)^-1 k, k the last stage's slope, into `out`
  void linearized_guess(int i, double share, double shg, VectorXd& out);
  bool refresh(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t, int i);
  // M = I - h g dadv - (h g)^2 dadq factored.
  void factor(double hg);
  // dz_ = (I - h g J)^-1 residual_ by M's factors.
  void solve(double hg);

  NewtonSettings settings_;
  Eigen::MatrixXd dadq_, dadv_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  Eigen::MatrixXd increments_;  // the step's stage increments Z_i (rows)
  bool jacobian_ = false, slow_ = false;
  double factored_ = 0.0;  // the h g of lu_ (0: none)
  double eta_ = 1.0;       // theta / (1 - theta) of the last iteration that converged
  VectorXd scale_, z_, known_, residual_, dz_, rhs_, qi_, vi_, ai_, behind_, trial_;
};

// The trial step of a tableau: an ImplicitTrial (with these settings) for an implicit one, else a Trial.
std::unique_ptr<Trial> make_trial(const Pair& pair, int nv, const pinocchio::Model* group,
                                  const NewtonSettings& settings);

// Throws std::invalid_argument (naming `where`) unless nodes (s >= 1), coupling (s x s, lower triangular; with a
// non-zero diagonal entry, a zero first row: an explicit first stage) and weights (s) make one tableau.
void check_tableau(const Pair& pair, const char* where);

}  // namespace pinstab
