// pinstab._compiled.kkt_cost_split: a measurement, not a path (benchmarks/kkt_sparsity.py, issue 35 Deliver 2): the
// cost of each part of one core evaluation (cpp/core_kernel.cpp) and of the sparse factorizations that could replace
// its dense KKT solve (cpp/kkt_solve.hpp), timed side by side on the same problem, with their accelerations so the
// caller measures their accuracy against an independent reference.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <ctime>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>

#include "core_rows.hpp"
#include "kkt_solve.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

using Sparse = Eigen::SparseMatrix<double>;

double thread_seconds() {
  timespec now;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// A sparse matrix of a fixed pattern refilled from a dense one: the entries' positions, gathered at each evaluation.
struct Gathered {
  Sparse matrix;
  std::vector<std::pair<int, int>> at;  // (row, column) of each stored value, in storage order
  void pattern(const Eigen::MatrixXd& mask) {
    matrix = mask.sparseView(0.0, 0.0);  // entries that are not zero in the mask
    matrix.makeCompressed();
    at.clear();
    for (int column = 0; column < matrix.outerSize(); ++column) {
      for (Sparse::InnerIterator it(matrix, column); it; ++it) at.emplace_back(it.row(), it.col());
    }
  }
  void fill(const Eigen::MatrixXd& dense) {
    double* values = matrix.valuePtr();
    for (size_t k = 0; k < at.size(); ++k) values[k] = dense(at[k].first, at[k].second);
  }
};

// The problem of one core evaluation at (q, v): M, f = -h, G and rhs = -gamma0 (the stabilization term left out: it
// costs O(rows) and changes no factorization), from the core's own pass and rows.
struct Problem {
  Eigen::MatrixXd mass, jacobian;
  VectorXd force, rhs;
};

void pass(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& q, const VectorXd& v) {
  pinocchio::computeAllTerms(model, data, q, v);
  pinocchio::updateFramePlacements(model, data);
  data.M.triangularView<Eigen::StrictlyLower>() = data.M.transpose().triangularView<Eigen::StrictlyLower>();
}

void rows(const pinocchio::Model& model, pinocchio::Data& data, const std::vector<RowBlock>& blocks,
          const std::vector<int>& offsets, const VectorXd& q, Problem& problem, VectorXd& phi, VectorXd& time_term) {
  for (size_t k = 0; k < blocks.size(); ++k) {
    const int offset = offsets[k], count = blocks[k].rows();
    block_residual(model, data, blocks[k], q, 0.0, phi.segment(offset, count));
    block_jacobian(model, data, blocks[k], 0.0, problem.jacobian.middleRows(offset, count),
                   time_term.segment(offset, count));
    block_drift(model, data, blocks[k], 0.0, problem.rhs.segment(offset, count));
  }
  problem.rhs = -problem.rhs;
}

// Seconds per call of each named part, the median over `rounds` rounds of `repeats` calls each, the parts interleaved
// within each round.
std::map<std::string, double> timed(const std::vector<std::pair<std::string, std::function<void()>>>& parts,
                                    int rounds, int repeats) {
  std::map<std::string, std::vector<double>> samples;
  for (int round = 0; round < rounds; ++round) {
    for (const auto& [name, part] : parts) {
      const double began = thread_seconds();
      for (int k = 0; k < repeats; ++k) part();
      samples[name].push_back((thread_seconds() - began) / repeats);
    }
  }
  std::map<std::string, double> medians;
  for (auto& [name, values] : samples) {
    std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
    medians[name] = values[values.size() / 2];
  }
  return medians;
}

nb::dict kkt_cost_split(nb::handle python_model_object, const std::vector<RowBlock>& blocks, const VectorXd& q,
                        const VectorXd& v, const VectorXd& q_other, int rounds, int repeats, double regularization) {
  const pinocchio::Model& model = python_model(python_model_object.ptr());
  pinocchio::Data data = light_data(model);
  std::vector<int> offsets;
  int count = 0;
  for (const RowBlock& block : blocks) {
    if (block.kind == RowKind::python) throw std::invalid_argument("kkt_cost_split: a block of Python rows");
    offsets.push_back(count);
    count += block.rows();
  }
  const int nv = model.nv;
  Problem problem{Eigen::MatrixXd::Zero(nv, nv), Eigen::MatrixXd::Zero(count, nv), VectorXd::Zero(nv),
                  VectorXd::Zero(count)};
  VectorXd phi = VectorXd::Zero(count), time_term = VectorXd::Zero(count);

  // the patterns: M's from the tree (M(i, j) != 0 only where one dof is an ancestor of the other), G's where it is
  // not zero at q or at q_other (both configurations' Jacobians)
  Eigen::MatrixXd mass_mask = Eigen::MatrixXd::Zero(nv, nv);
  for (int i = 0; i < nv; ++i) {
    for (int j = i; j < i + data.nvSubtree_fromRow[static_cast<size_t>(i)]; ++j) mass_mask(i, j) = mass_mask(j, i) = 1;
  }
  pass(model, data, q_other, v);
  rows(model, data, blocks, offsets, q_other, problem, phi, time_term);
  Eigen::MatrixXd jacobian_mask = (problem.jacobian.array() != 0.0).cast<double>().matrix();
  pass(model, data, q, v);
  rows(model, data, blocks, offsets, q, problem, phi, time_term);
  jacobian_mask = jacobian_mask.cwiseMax((problem.jacobian.array() != 0.0).cast<double>().matrix());
  problem.mass = data.M;
  problem.force = -data.nle;
  const CoreSolve settings;

  // the dense solve of today, part by part (KktSolve's steps)
  Eigen::LLT<Eigen::MatrixXd> mass_llt(nv), inner(count);
  DelassusPseudoInverse pseudo_inverse;
  Eigen::MatrixXd spread(nv, count), delassus(count, count);
  VectorXd free(nv), multipliers(count), dense_a(nv);
  mass_llt.compute(problem.mass);
  spread = mass_llt.solve(problem.jacobian.transpose());
  delassus.noalias() = problem.jacobian * spread;
  inner.compute(delassus);
  const bool dependent = inner.info() != Eigen::Success ||
                         !independent_by_margin(inner.matrixLLT().diagonal(), delassus.diagonal().maxCoeff(),
                                                settings.direct_pivot);
  pseudo_inverse.compute(delassus, settings.cutoff);
  const auto delassus_inverse = [&](const VectorXd& x) -> VectorXd {
    return dependent ? pseudo_inverse.apply(x) : VectorXd(inner.solve(x));
  };
  const auto dense_solve = [&] {  // lambda0 = D^-1 demand, then KktSolve::refine's step
    free = mass_llt.solve(problem.force);
    multipliers = delassus_inverse(problem.rhs - problem.jacobian * free);
    dense_a = free + spread * multipliers;
    multipliers += delassus_inverse(problem.rhs - problem.jacobian * dense_a);
    dense_a = free + spread * multipliers;
  };
  dense_solve();
  KktSolve kkt, structured;
  const KktOutcome outcome = kkt.solve(problem.mass, problem.force, problem.jacobian, problem.rhs, settings, true);
  const KktOutcome structured_outcome =
      structured.solve(model, data, problem.force, problem.jacobian, problem.rhs, settings, true);

  // Pinocchio's tree-sparse LDL^T of M (cholesky::decompose: O(nv depth)), M^-1 G^T by its substitutions
  Eigen::MatrixXd tree_spread(nv, count);
  const auto tree_delassus = [&] {
    tree_spread = problem.jacobian.transpose();
    pinocchio::cholesky::solve(model, data, tree_spread);
    delassus.noalias() = problem.jacobian * tree_spread;
  };
  pinocchio::cholesky::decompose(model, data);
  tree_delassus();
  VectorXd tree_a = problem.force;  // its own solve, as dense_solve's on its factors
  pinocchio::cholesky::solve(model, data, tree_a);
  {
    Eigen::LLT<Eigen::MatrixXd> tree_inner(delassus);
    DelassusPseudoInverse tree_pseudo_inverse;
    tree_pseudo_inverse.compute(delassus, settings.cutoff);
    const auto inverse = [&](const VectorXd& x) -> VectorXd {
      return dependent ? tree_pseudo_inverse.apply(x) : VectorXd(tree_inner.solve(x));
    };
    const VectorXd tree_free = tree_a;
    VectorXd lambda = inverse(problem.rhs - problem.jacobian * tree_free);
    tree_a = tree_free + tree_spread * lambda;
    lambda += inverse(problem.rhs - problem.jacobian * tree_a);
    tree_a = tree_free + tree_spread * lambda;
  }

  // Eigen's sparse Cholesky of M, the sparse Delassus matrix G M^-1 G^T and its sparse Cholesky (the patterns'
  // orderings analysed once: AMD)
  Gathered mass_sparse, jacobian_sparse;
  mass_sparse.pattern(mass_mask);
  jacobian_sparse.pattern(jacobian_mask);
  Eigen::SimplicialLLT<Sparse> sparse_mass, sparse_inner;
  Sparse sparse_spread, sparse_delassus;
  VectorXd sparse_a(nv), sparse_free(nv), sparse_multipliers(count);
  const auto to_sparse = [&] {
    mass_sparse.fill(problem.mass);
    jacobian_sparse.fill(problem.jacobian);
  };
  const auto sparse_schur_delassus = [&] {
    sparse_spread = sparse_mass.solve(Sparse(jacobian_sparse.matrix.transpose()));
    sparse_delassus = (jacobian_sparse.matrix * sparse_spread).pruned();
  };
  to_sparse();
  sparse_mass.analyzePattern(mass_sparse.matrix);
  sparse_mass.factorize(mass_sparse.matrix);
  sparse_schur_delassus();
  sparse_inner.analyzePattern(sparse_delassus);
  sparse_inner.factorize(sparse_delassus);
  const auto sparse_schur_solve = [&] {  // as dense_solve (no pseudo-inverse here: measured where rows are independent)
    sparse_free = sparse_mass.solve(problem.force);
    sparse_multipliers = sparse_inner.solve(problem.rhs - jacobian_sparse.matrix * sparse_free);
    sparse_a = sparse_free + sparse_spread * sparse_multipliers;
    sparse_multipliers += sparse_inner.solve(problem.rhs - jacobian_sparse.matrix * sparse_a);
    sparse_a = sparse_free + sparse_spread * sparse_multipliers;
  };
  sparse_schur_solve();

  // Eigen's sparse LDL^T of the quasi-definite KKT matrix [M G^T; G -eps I] (eps = regularization times M's largest
  // diagonal entry), refined on the exact KKT system twice
  const int n = nv + count;
  Eigen::MatrixXd kkt_mask = Eigen::MatrixXd::Zero(n, n), kkt_dense = Eigen::MatrixXd::Zero(n, n);
  kkt_mask.topLeftCorner(nv, nv) = mass_mask;
  kkt_mask.bottomLeftCorner(count, nv) = jacobian_mask;
  kkt_mask.topRightCorner(nv, count) = jacobian_mask.transpose();
  kkt_mask.bottomRightCorner(count, count).setIdentity();
  Gathered kkt_sparse;
  kkt_sparse.pattern(kkt_mask);
  const double epsilon = regularization * problem.mass.diagonal().maxCoeff();
  Eigen::SimplicialLDLT<Sparse> sparse_kkt;
  VectorXd kkt_rhs(n), kkt_x(n), kkt_a(nv);
  const auto to_kkt = [&] {
    kkt_dense.topLeftCorner(nv, nv) = problem.mass;
    kkt_dense.bottomLeftCorner(count, nv) = problem.jacobian;
    kkt_dense.topRightCorner(nv, count) = problem.jacobian.transpose();
    kkt_dense.bottomRightCorner(count, count).diagonal().setConstant(-epsilon);
    kkt_sparse.fill(kkt_dense);
  };
  const auto kkt_solve = [&] {
    kkt_rhs << problem.force, problem.rhs;
    kkt_x = sparse_kkt.solve(kkt_rhs);
    for (int step = 0; step < 2; ++step) {  // the residual of the unregularized system: M a - G^T l - f, G a - rhs
      VectorXd miss(n);
      miss.head(nv) = problem.force - problem.mass * kkt_x.head(nv) - problem.jacobian.transpose() * kkt_x.tail(count);
      miss.tail(count) = problem.rhs - problem.jacobian * kkt_x.head(nv);
      kkt_x += sparse_kkt.solve(miss);
    }
    kkt_a = kkt_x.head(nv);
  };
  to_kkt();
  sparse_kkt.analyzePattern(kkt_sparse.matrix);
  sparse_kkt.factorize(kkt_sparse.matrix);
  kkt_solve();  // multipliers: kkt_x.tail = -lambda (the sign of G^T's block); accelerations alone compared

  std::map<std::string, double> seconds;
  {
    nb::gil_scoped_release released;
    seconds = timed(
        {
            {"pass (kinematics, M, h)", [&] { pass(model, data, q, v); }},
            {"of which M (crba)", [&] { pinocchio::crba(model, data, q); }},
            {"rows", [&] { rows(model, data, blocks, offsets, q, problem, phi, time_term); }},
            {"dense: M factorization", [&] { mass_llt.compute(problem.mass); }},
            {"dense: Delassus", [&] {
               spread = mass_llt.solve(problem.jacobian.transpose());
               delassus.noalias() = problem.jacobian * spread;
             }},
            {"dense: Delassus factorization", [&] {
               inner.compute(delassus);
               if (dependent) pseudo_inverse.compute(delassus, settings.cutoff);
             }},
            {"dense: solve", dense_solve},
            {"dense: KktSolve::solve", [&] {
               kkt.solve(problem.mass, problem.force, problem.jacobian, problem.rhs, settings, true);
             }},
            {"structured: KktSolve::solve", [&] {
               structured.solve(model, data, problem.force, problem.jacobian, problem.rhs, settings, true);
             }},
            {"tree: M factorization", [&] { pinocchio::cholesky::decompose(model, data); }},
            {"tree: Delassus", tree_delassus},
            {"sparse: to sparse", to_sparse},
            {"sparse: M factorization", [&] { sparse_mass.factorize(mass_sparse.matrix); }},
            {"sparse: Delassus", sparse_schur_delassus},
            {"sparse: Delassus factorization", [&] { sparse_inner.factorize(sparse_delassus); }},
            {"sparse: solve", sparse_schur_solve},
            {"sparse KKT: to sparse", to_kkt},
            {"sparse KKT: factorization", [&] { sparse_kkt.factorize(kkt_sparse.matrix); }},
            {"sparse KKT: solve", kkt_solve},
        },
        rounds, repeats);
  }
  // the state the parts leave is the problem's again (the crba part wrote M's upper triangle with the same values)
  nb::dict result;
  result["seconds"] = seconds;
  result["mass"] = problem.mass;
  result["force"] = problem.force;
  result["jacobian"] = problem.jacobian;
  result["rhs"] = problem.rhs;
  result["dependent"] = dependent;
  result["outcome"] = static_cast<int>(outcome);
  result["structured_outcome"] = static_cast<int>(structured_outcome);
  result["structured_sparse"] = structured.sparse();
  result["nnz"] = std::map<std::string, long>{{"M", mass_sparse.matrix.nonZeros()},
                                                {"G", jacobian_sparse.matrix.nonZeros()},
                                                {"D", sparse_delassus.nonZeros()},
                                                {"KKT", kkt_sparse.matrix.nonZeros()}};
  result["acceleration"] = std::map<std::string, VectorXd>{
      {"dense", dense_a}, {"KktSolve", kkt.acceleration()}, {"structured", structured.acceleration()}, {"tree", tree_a},
      {"sparse", sparse_a}, {"sparse KKT", kkt_a}};
  return result;
}

}  // namespace

void bind_kkt_sparsity(nb::module_& m) {
  m.def("kkt_cost_split", &kkt_cost_split, "model"_a, "blocks"_a, "q"_a, "v"_a, "q_other"_a, "rounds"_a,
        "repeats"_a, "regularization"_a,
        "A measurement (benchmarks/kkt_sparsity.py): seconds per call of each part of a core evaluation at (q, v) "
        "(no stabilization term, t = 0) and of the sparse factorizations that could replace its dense KKT solve "
        "(Pinocchio's tree LDL^T of M, Eigen's sparse Cholesky of M and of the Delassus matrix, Eigen's sparse "
        "LDL^T of the KKT matrix regularized by `regularization` times M's largest diagonal entry), medians of "
        "`rounds` interleaved rounds of `repeats` calls; G's pattern where it is not zero at q or q_other. Also the "
        "problem (mass, force, jacobian, rhs) and each method's accelerations.");
}

}  // namespace pinstab
