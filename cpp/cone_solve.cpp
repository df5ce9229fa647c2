#include "cone_solve.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include <pinocchio/algorithm/delassus-operator.hpp>
#include <pinocchio/algorithm/solvers/admm-solver.hpp>
#include <pinocchio/algorithm/solvers/pgs-solver.hpp>
#include <pinocchio/constraints.hpp>

#include "torsion_cone.hpp"

namespace pinstab {

namespace {

using ConstraintModel = pinocchio::ConstraintModelTpl<double, 0, pinocchio::ConstraintCollectionDefaultTpl>;
using ConstraintData = pinocchio::ConstraintDataTpl<double, 0, pinocchio::ConstraintCollectionDefaultTpl>;

// Feasibility and complementarity tolerances (absolute and relative) of a solver's settings, NCP mode.
template <class Settings>
void set_tolerances(Settings& settings, double tolerance, int max_iterations) {
  settings.max_iterations = static_cast<std::size_t>(max_iterations);
  settings.solve_ncp = true;
  settings.absolute_feasibility_tol = tolerance;
  settings.relative_feasibility_tol = tolerance;
  settings.absolute_complementarity_tol = tolerance;
  settings.relative_complementarity_tol = tolerance;
}

// Each row's unit (t1, t2, n per contact): max(mu, 1) on the tangential rows, 1 on the normal one.
Eigen::VectorXd cone_scales(const Eigen::VectorXd& mus) {
  Eigen::VectorXd scales(3 * mus.size());
  for (Eigen::Index i = 0; i < mus.size(); ++i) {
    const double s = std::max(mus(i), 1.0);
    scales.segment<3>(3 * i) << s, s, 1.0;
  }
  return scales;
}

}  // namespace

double ncp_residual(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& impulses,
                    const Eigen::VectorXd& mus) {
  return torsion_residual(delassus, g, impulses, mus, Eigen::VectorXd::Zero(mus.size()));
}

// Pinocchio's solvers, their settings and results, and the cones of the last friction coefficients.
struct ConeSolver::Solvers {
  pinocchio::ADMMConstraintSolver admm;
  pinocchio::ADMMSolverSettings admm_settings;
  pinocchio::ADMMSolverResult admm_result;
  pinocchio::PGSConstraintSolver pgs;
  pinocchio::PGSSolverSettings pgs_settings;
  pinocchio::PGSSolverResult pgs_result;
  Eigen::VectorXd mus;  // the cones' friction coefficients (unscaled)
  std::vector<ConstraintModel> models;
  std::vector<ConstraintData> datas;
  pinocchio::Model empty;

  Solvers(int size) : admm(static_cast<std::size_t>(size)), pgs(static_cast<std::size_t>(size)) {}

  // Constraint models carrying only the cones |lambda_t| <= min(mu, 1) lambda_n (what the solvers read of them).
  void set_cones(const Eigen::VectorXd& coefficients) {
    if (coefficients.size() == mus.size() && coefficients == mus) return;
    mus = coefficients;
    models.clear();
    datas.clear();
    for (Eigen::Index i = 0; i < mus.size(); ++i) {
      pinocchio::PointContactConstraintModel cone(empty, 0, pinocchio::SE3::Identity(), 0, pinocchio::SE3::Identity());
      cone.setFriction(std::min(mus(i), 1.0));
      models.emplace_back(cone);
      datas.push_back(models.back().createData());
    }
  }
};

ConeSolver::ConeSolver(int size, double tolerance, int max_iterations, int lanczos_size, int check_every,
                       double settled)
    : solvers_(std::make_unique<Solvers>(std::max(size, 3))),
      max_iterations_(max_iterations),
      check_every_(check_every),
      settled_(settled) {
  set_tolerances(solvers_->admm_settings, tolerance, max_iterations);
  solvers_->admm_settings.admm_update_rule = pinocchio::ADMMUpdateRule::SPECTRAL;
  solvers_->admm_settings.lanczos_size = static_cast<std::size_t>(lanczos_size);
  set_tolerances(solvers_->pgs_settings, tolerance, max_iterations);
}

ConeSolver::~ConeSolver() = default;

template <class Result>
void read_status(const Result& result, const char* method, ConeStatus& status) {
  status.method = method;
  status.iterations = static_cast<long>(result.iterations);
  status.primal_feasibility = result.primal_feasibility;
  status.dual_feasibility = result.dual_feasibility;
  status.complementarity = result.complementarity;
}

// The impulses (unscaled) of `solver` on the scaled problem, each run from zero: for `every` iterations, then half as
// many, then twice, four times as many and so on up to `max_iterations` (each run the first iterations of the longest:
// the answers a single run passes through): the answer of the run where the solver meets its own tolerance, else the
// best one (least `residual`, its ratio to the residual accepted) once a run that passes (ratio <= 1) no longer shrinks
// it by `settled` against the run of half its iterations (the first run against the half run: a residual settled
// within `every` iterations, as on redundant contacts, is found without a run of twice as many); `iterations` the
// iterations of all the runs. One Delassus operator serves every run (each run factors it anew).
template <class Solver, class Settings, class Result, class Models, class Datas>
Eigen::VectorXd solve_in_rounds(Solver& solver, Settings settings, Result& result, const Eigen::MatrixXd& symmetric,
                                const Eigen::VectorXd& scaled_g, const Models& models, Datas& datas,
                                const Eigen::VectorXd& scales, int max_iterations, int every, double settled,
                                const std::function<double(const Eigen::VectorXd&)>& residual, long& iterations) {
  Eigen::VectorXd scaled(scaled_g.size()), impulses(scaled_g.size()), best(scaled_g.size());
  double least = std::numeric_limits<double>::infinity();
  bool kept = false;
  pinocchio::DelassusOperatorDense operator_(symmetric);
  iterations = 0;
  // one run of `size` iterations from zero: whether the solver met its tolerance; its answer's ratio (the best kept)
  const auto run = [&](long size, double& ratio) {
    settings.max_iterations = static_cast<std::size_t>(size);
    result.clearConstraintImpulseGuess();
    solver.solve(operator_, scaled_g, models, datas, settings, result);
    iterations += static_cast<long>(result.iterations);
    result.retrieveConstraintImpulses(scaled);
    impulses = scales.cwiseProduct(scaled);
    if (result.converged) return true;
    const double found = residual(impulses);
    ratio = std::isnan(found) ? least : found;
    if (ratio < least || !kept) least = ratio, best = impulses, kept = true;
    return false;
  };
  const long first = std::min(every, max_iterations);
  double last = 0.0, ratio = 0.0, half = 0.0;
  if (run(first, last)) return impulses;
  if (first == max_iterations) return best;
  if (first > 1) {
    if (run(first / 2, half)) return impulses;
    if (least <= 1.0 && last > settled * half) return best;
  }
  for (long size = std::min<long>(2 * first, max_iterations);; size = std::min<long>(2 * size, max_iterations)) {
    if (run(size, ratio)) return impulses;
    if ((least <= 1.0 && ratio > settled * last) || size == max_iterations) break;
    last = ratio;
  }
  return best;
}

Eigen::VectorXd ConeSolver::solve(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g,
                                  const Eigen::VectorXd& mus, double check_rtol) {
  Solvers& s = *solvers_;
  s.set_cones(mus);
  const Eigen::VectorXd scales = cone_scales(mus);
  const Eigen::MatrixXd scaled = scales.asDiagonal() * delassus * scales.asDiagonal();
  const Eigen::VectorXd scaled_g = scales.cwiseProduct(g);
  const Eigen::MatrixXd symmetric = 0.5 * (scaled + scaled.transpose());
  const auto residual = [&](const Eigen::VectorXd& impulses) {
    check(delassus, g, impulses, mus, check_rtol);
    return status_.residual / status_.accepted;
  };
  long iterations = 0;
  Eigen::VectorXd impulses = solve_in_rounds(s.admm, s.admm_settings, s.admm_result, symmetric, scaled_g, s.models,
                                             s.datas, scales, max_iterations_, check_every_, settled_, residual, iterations);
  read_status(s.admm_result, "ADMM", status_);
  status_.iterations = iterations;
  if (check(delassus, g, impulses, mus, check_rtol)) return impulses;
  impulses = solve_in_rounds(s.pgs, s.pgs_settings, s.pgs_result, symmetric, scaled_g, s.models, s.datas, scales,
                             max_iterations_, check_every_, settled_, residual, iterations);
  read_status(s.pgs_result, "PGS", status_);
  status_.iterations = iterations;
  check(delassus, g, impulses, mus, check_rtol);
  return impulses;
}

Eigen::VectorXd ConeSolver::solve_torsion(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g,
                                          const Eigen::VectorXd& mus, const Eigen::VectorXd& torsions,
                                          double check_rtol) {
  const Eigen::VectorXd impulses =
      torsion_admm(delassus, g, mus, torsions, solvers_->admm_settings.absolute_feasibility_tol, max_iterations_,
                   status_);
  check(delassus, g, impulses, mus, check_rtol, torsions);
  return impulses;
}

bool ConeSolver::check(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& impulses,
                       const Eigen::VectorXd& mus, double check_rtol, const Eigen::VectorXd& torsions) {
  status_.residual = torsions.size() ? torsion_residual(delassus, g, impulses, mus, torsions)
                                     : ncp_residual(delassus, g, impulses, mus);
  double scale = g.size() ? g.cwiseAbs().maxCoeff() : 0.0;
  if (impulses.allFinite() && g.size()) scale = std::max(scale, (delassus * impulses).cwiseAbs().maxCoeff());
  status_.accepted = check_rtol * scale;
  status_.converged = status_.residual <= status_.accepted;
  return status_.converged;
}

}  // namespace pinstab
