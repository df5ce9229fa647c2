#pragma once

#include <utility>

#include "kernels.hpp"
#include "spectrum.hpp"
#include "world_bias.hpp"

namespace pinstab {

// The KKT pattern of pinstab.banded.BandedDynamics (built in Python once per scene).
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
  BandedKernel(const pinocchio::Model& model, BandedPattern pattern, GramSpectrum::Pattern gram, double kp, double kd,
               double pivot_tolerance);
  bool acceleration(const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) override;
  int nv() const override { return model_.nv; }
  bool singular() const { return singular_; }
  VectorXd multipliers() const;
  // max |phi| [m] and max |G v| [m/s] over the closures' rows at (q, v): the stepping loop's drift check
  std::pair<double, double> violation(const VectorXd& q, const VectorXd& v);
  // sigma_r / sigma_1 of the closures' Jacobian G at q (the passage watch's sample), by GramSpectrum
  double relative_singular_value(const VectorXd& q, int rank);

 private:
  void jacobian_values();
  void place_points();

  pinocchio::Model model_;
  pinocchio::Data data_;
  WorldBias world_bias_;
  bool world_;  // WorldBias applies to the model's joints
  BandedPattern pattern_;
  GramSpectrum spectrum_;
  double kp_, kd_, pivot_tolerance_;
  Eigen::MatrixXd points_, terms_, coefficients_, ab_;
  VectorXd rows_, lever_, values_, rhs_, g_values_;
  std::vector<int> pivots_;
  bool singular_ = false;
};

}  // namespace pinstab
