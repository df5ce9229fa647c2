#pragma once

#include <utility>

#include "kernels.hpp"
#include "spectrum.hpp"
#include "world_bias.hpp"

namespace pinstab {

// The KKT pattern of pinstab.paths.banded.BandedDynamics (built in Python once per scene).
struct BandedPattern {
  VectorXi carried, joints;       // points carried by bodies, and their joints
  Eigen::MatrixXd local;          // (carried, 3) the points in their joints' frames [m]
  Eigen::MatrixXd fixed_points;   // (3, points) world points (zero where carried) [m]
  Csr row_map;                    // (rows, 3 points) closure rows from the per-point terms
  VectorXi g_columns;             // G's entries: their columns
  Eigen::MatrixXd g_linear;       // (3, entries) linear part of each entry's coefficient
  Csr g_map;                      // (3 entries, 3 points) lever part, linear in the points
  VectorXi m_rows, m_cols;        // M's upper-triangle entries
  VectorXi m_off;                 // which of them (indices) appear again below the diagonal
  VectorXi scatter;               // where [M upper, M lower, G, G^T] go in the band storage (column-major)
  VectorXi acceleration_slots, row_slots;
  int band = 0;
};

class BandedKernel : public Kernel {
 public:
  // data: a Data of the model to compute in (shared with the caller, each evaluation recomputing what it reads), or
  // nullptr for one of its own
  BandedKernel(const pinocchio::Model& model, BandedPattern pattern, GramSpectrum::Pattern gram, double kp, double kd,
               double pivot_tolerance, pinocchio::Data* data = nullptr);
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                    VectorXd& a) override;
  int nv() const override { return model_.nv; }
  // the last evaluation met a small pivot and iterative refinement did not bring its solution to rounding
  bool singular() const { return singular_; }
  // evaluations that met a small pivot and were refined to rounding (used)
  long refinements() const { return refinements_; }
  // the last evaluation's smallest |pivot| over its largest
  double pivot_ratio() const { return pivot_ratio_; }
  VectorXd multipliers() const;
  // max |phi| [m] and max |G v| [m/s] over the closures' rows at (q, v): the stepping loop's drift check
  std::pair<double, double> violation(const VectorXd& q, const VectorXd& v);
  // sigma_r / sigma_1 of the closures' Jacobian G at q (the passage watch's sample), by GramSpectrum
  double relative_singular_value(const VectorXd& q, int rank);
  // (phi [m], G's entries in the pattern's order) at q: the closures' residuals and Jacobian
  std::pair<VectorXd, VectorXd> values(const VectorXd& q);
  // x = M^-1 G^T (G M^-1 G^T)^-1 rows at q (the KKT system with [0; rows] on its right), refined near a small
  // pivot; false where the matrix is singular to rounding (redundant rows, a singular configuration)
  bool project(const VectorXd& q, const VectorXd& rows, VectorXd& x);

 private:
  enum class Outcome { solved, refined, singular };
  void assemble_matrix();
  Outcome solve_assembled();
  void jacobian_values();
  void place_points();
  void closure_rows(const Eigen::MatrixXd& per_point, VectorXd& rows);  // the rows' s . (T_b - T_a)
  void scatter(Eigen::MatrixXd& band) const;  // the KKT entries (values_) into band storage
  bool refine();

  // a pivot ratio below this: rows dependent to rounding (an exactly singular configuration, redundant rows),
  // left to the caller (the runs' evaluations near singular passages of the N-four-bar stay above 4e-9)
  static constexpr double REFINABLE = 1e-12;
  static constexpr int MAX_REFINEMENTS = 8;
  static constexpr double REFINED = 1e-15;  // a last correction this small relative to its part: converged

  pinocchio::Model model_;
  std::unique_ptr<pinocchio::Data> own_data_;  // when no Data was given
  pinocchio::Data& data_;
  WorldBias world_bias_;
  bool world_;  // WorldBias applies to the model's joints
  BandedPattern pattern_;
  GramSpectrum spectrum_;
  double kp_, kd_, pivot_tolerance_;
  Eigen::MatrixXd points_, terms_, ab_, kkt_;
  Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::RowMajor> flat_points_, raveled_;  // (3, points) raveled by row
  VectorXd rows_, lever_, values_, rhs_, g_values_, right_, correction_;
  long refinements_ = 0;
  double pivot_ratio_ = 0.0;
  std::vector<int> pivots_;
  bool singular_ = false;
};

}  // namespace pinstab
