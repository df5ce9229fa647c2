// One step of a diagonally implicit Runge-Kutta tableau (a_ij lower triangular, an explicit first stage, a non-zero
// diagonal below it) on the configuration group, its stages solved by a simplified Newton iteration: the only place
// the implicit schemes' arithmetic is (pinstab.integration.implicit names them). The fixed-step loop
// (advance_tableau), the error-controlled loop (attempt, adaptive_advance) and the Python step path (the bindings'
// one step) all take this step, so they take the same steps to the last bit.
//
// Stage i (i >= 1) solves, in the tangent space at the step's start (q0, v0), for its increment Z = (Zq, Zv):
//   Z = S_i + h g F(Z),  S_i = h sum_{j<i} a_ij k_j,  g = a_ii,
//   F(Z) = (slope(q0, q0 (+) Zq, v0 + Zv), a(t + c_i h, q0 (+) Zq, v0 + Zv)),
// then k_i = (Z - S_i) / (h g) (the slope the stage equation gives, not a further evaluation). The iteration matrix
// I - h g J with J = [[0, I], [dadq, dadv]] (the kernel's Jacobian) reduces by its 2 x 2 block structure to the
// nv x nv M = I - h g dadv - (h g)^2 dadq: dZv = M^-1 (r_v + h g dadq r_q), dZq = r_q + h g dZv
// (r = S_i + h g F(Z) - Z), from the guess Z = S_i + h g (I - h g J)^-1 k_(i-1). M's LU factors serve every stage of
// the same h g, the iterations and the steps that follow. The Jacobian (at a step's start) is kept while the
// iteration converges fast (rate theta <= 0.1), refreshed at the next step's start after a slower one, at a stage's
// iterate when the iterations left cannot converge at the rate seen (at most twice per stage), and at once (the step
// retried) when an iteration with an older one fails.
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
// stage's estimate) at most kappa; it gives up on a rate >= 1 or after max_iterations iterations.
struct NewtonSettings {
  double rtol, atol, kappa;
  int max_iterations;
};

// What Newton's iteration did over the steps: iterations (one evaluation each), Jacobians evaluated, LU
// factorizations of M, failures (a stage not solved: the step retried with a fresh Jacobian, else not taken).
struct NewtonCounts {
  long iterations = 0, jacobians = 0, factorizations = 0, failures = 0;
};

// A step whose stage could not be solved even with a fresh Jacobian (pinstab._compiled.NewtonFailure; the Python
// step raises pinstab.errors.NewtonError from it).
class NewtonFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ImplicitTrial : public Trial {
 public:
  ImplicitTrial(const Pair& pair, int nv, const pinocchio::Model* group, const NewtonSettings& settings);
  // Trial::take, the stages solved; with a stiffly accurate tableau the new point's slope is the last stage's
  // (has_end). False with unconverged when a stage was not solved (failed_stage, residual: the last scaled increment
  // norm, iterations: of the last attempt).
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
  bool refresh(Kernel& kernel, const VectorXd& tau, const VectorXd& q, const VectorXd& v, double t, int i);
  // M = I - h g dadv - (h g)^2 dadq factored.
  void factor(double hg);
  // dz_ = (I - h g J)^-1 residual_ by M's factors.
  void solve(double hg);

  NewtonSettings settings_;
  Eigen::MatrixXd dadq_, dadv_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  bool jacobian_ = false, fresh_ = false, slow_ = false;
  double factored_ = 0.0;  // the h g of lu_ (0: none)
  double eta_ = 1.0;       // theta / (1 - theta) of the last iteration that converged
  VectorXd scale_, z_, known_, residual_, dz_, rhs_, qi_, vi_, ai_;
};

// The trial step of a tableau: an ImplicitTrial (with these settings) for an implicit one, else a Trial.
std::unique_ptr<Trial> make_trial(const Pair& pair, int nv, const pinocchio::Model* group,
                                  const NewtonSettings& settings);

// Throws std::invalid_argument (naming `where`) unless nodes (s >= 1), coupling (s x s, lower triangular; with a
// non-zero diagonal entry, a zero first row: an explicit first stage) and weights (s) make one tableau.
void check_tableau(const Pair& pair, const char* where);

}  // namespace pinstab
