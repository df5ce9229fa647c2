// The frictional contact problem on exact round cones (pinstab.solvers.ncp), checked: Pinocchio's ADMM in NCP mode on
// the problem with steep cones scaled to at most 1, its answer measured by the natural map of the De Saxce law
// (ncp_residual) and kept within check_rtol of the problem's velocity scale, else Pinocchio's PGS in NCP mode on the
// same problem, checked the same way. The only place these rules are: NcpSolver.solve_contacts and the compiled
// Moreau-Jean step (cpp/cone_step.hpp) call it.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>

namespace pinstab {

// How far `impulses` (Pinocchio's order: t1, t2, n per contact) are from solving the problem (D, g) with friction
// coefficients mus [-], in the units of g: the largest contact's natural map |lambda - P_K(lambda - rho (sigma + mu
// |sigma_t| e_n))| / rho, sigma = D lambda + g, rho = 1 / trace D; 0 exactly at a solution, infinite for a
// non-finite lambda.
double ncp_residual(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& impulses,
                    const Eigen::VectorXd& mus);

// How the last checked solve ended: the solver whose answer was kept ("ADMM" or "PGS"; the last one tried when none
// passed), its iterations and primal and dual feasibility and complementarity residuals, whether the answer passed
// the check, its ncp_residual and the residual accepted [units of g].
struct ConeStatus {
  std::string method = "ADMM";
  long iterations = 0;
  bool converged = false;
  double primal_feasibility = 0.0, dual_feasibility = 0.0, complementarity = 0.0;
  double residual = 0.0, accepted = 0.0;
};

// ADMM and PGS in NCP mode with every feasibility and complementarity tolerance (absolute and relative) at
// `tolerance` and at most `max_iterations` each (ADMM: the spectral rho rule, D's largest eigenvalue estimated by
// `lanczos_size` Lanczos steps), each run from zero for `check_every` iterations, then half as many, then twice as many
// and so on, its answer checked after each run: the solve ends at the run where the solver meets its own tolerance, or
// once an answer passes the check and a run no longer shrinks the residual by the factor `settled` against the run of
// half its iterations (the first run against the half run) (the best answer kept). On
// redundant contacts (D rank-deficient) the impulses are not unique and drift within the set of solutions, which the
// solvers' own tolerances (on the change of the impulses) never meet, while the contact velocities, which the check
// measures, settle.
class ConeSolver {
 public:
  ConeSolver(int size, double tolerance, int max_iterations, int lanczos_size, int check_every, double settled);
  ~ConeSolver();
  ConeSolver(const ConeSolver&) = delete;
  ConeSolver& operator=(const ConeSolver&) = delete;
  // The impulses (Pinocchio's order) of the problem (D, g) (Pinocchio's order, 3 rows per contact) with friction
  // coefficients mus [-]; status() says which solver's answer it is and whether it passed the check at check_rtol.
  Eigen::VectorXd solve(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& mus,
                        double check_rtol);
  // The same with torsion rows (cpp/torsion_cone.hpp's layout; torsion lengths torsions [m], k): its ADMM (method
  // "ADMM-torsion", no fallback), checked by torsion_residual at check_rtol.
  Eigen::VectorXd solve_torsion(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& mus,
                                const Eigen::VectorXd& torsions, double check_rtol);
  const ConeStatus& status() const { return status_; }
  int max_iterations() const { return max_iterations_; }

 private:
  struct Solvers;
  bool check(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& impulses,
             const Eigen::VectorXd& mus, double check_rtol, const Eigen::VectorXd& torsions = Eigen::VectorXd());
  std::unique_ptr<Solvers> solvers_;
  int max_iterations_, check_every_;
  double settled_;
  ConeStatus status_;
};

}  // namespace pinstab
