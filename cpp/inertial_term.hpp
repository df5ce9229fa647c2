// Mukharlyamov's extended system in its inertial variant (A = Lambda(q); docs/mathematics.md section 3): the term
// -S phi - K rate with S = D H and K = D B - dD/dt Lambda, D = G M^-1 G^T and Lambda = D^+, dD/dt by a forward
// difference along the velocity. pinstab.stabilizers.mukharlyamov computes S and K with inertial_matrices, and the core
// kernel (cpp/core_kernel.cpp) its term with InertialPass.
#pragma once

#include <utility>
#include <vector>

#include "core_rows.hpp"
#include "kernels.hpp"

namespace pinstab {

// The variant's given matrices: H (s x columns: the rows of phi it weighs) [N/m, N m/rad], B (s x s) [N s/m,
// N m s/rad], the difference step of dD/dt [s] and the cutoff of Lambda = D^+ (relative: DelassusPseudoInverse,
// cpp/kkt_solve.hpp).
struct InertialGains {
  Eigen::MatrixXd stiffness, damping;
  double rate_step = 1e-7, cutoff = 1e-10;
};

// (S = D H [1/s^2], K = D B - (D_ahead - D) / rate_step D^+ [1/s]) with D = G M^-1 G^T at q and D_ahead at
// q (+) rate_step v [1/kg, 1/(kg m^2)], from M (both triangles set) and G there; NaN where D is not finite.
std::pair<Eigen::MatrixXd, Eigen::MatrixXd> inertial_matrices(const InertialGains& gains, const Eigen::MatrixXd& mass,
                                                              const Eigen::MatrixXd& jacobian,
                                                              const Eigen::MatrixXd& mass_ahead,
                                                              const Eigen::MatrixXd& jacobian_ahead);

// The inertial term on the core kernel's compiled rows: M and G at q from the kernel's pass, at q (+) rate_step v from
// a kinematics pass of its own (joint Jacobians, frame placements, M).
class InertialPass {
 public:
  InertialPass(const pinocchio::Model& model, InertialGains gains);
  // -S phi - K rate [m/s^2 or rad/s^2] at (t [s], q, v), phi zero on nonholonomic rows, rate = G v + g_t
  VectorXd term(const pinocchio::Model& model, const std::vector<RowBlock>& blocks, const std::vector<int>& offsets,
                double t, const VectorXd& q, const VectorXd& v, const Eigen::MatrixXd& mass,
                const Eigen::MatrixXd& jacobian, const VectorXd& phi, const VectorXd& rate);

 private:
  InertialGains gains_;
  pinocchio::Data ahead_;
  Eigen::MatrixXd jacobian_ahead_;
  VectorXd time_term_;
};

}  // namespace pinstab
