// The frictional contact problem of pinstab.solvers.ncp with torsion (soft-finger contacts, issue 36): a contact with
// a torsion length c > 0 [m] has a fourth row, its relative angular velocity about the normal, and a torque impulse
// there bounded as the event-driven modes bound it (pinstab.solvers.contact_modes.Spin): |lambda_tau| <= c lambda_n,
// beside |lambda_t| <= mu lambda_n. The contact's set K is the product of the round cone and the torsion interval over
// the same normal impulse; its De Saxce velocity sigma_n + mu |sigma_t| + c |sigma_tau| makes each friction dissipate
// at its bound when it slips (the law's complementarity lambda . s = 0 splits into the two Coulomb laws: a slip's force
// opposes it at mu lambda_n, a spin's torque at c lambda_n, each sticks inside its bound), the event modes' law.
// Pinocchio's solvers have no such set: the problem is solved here by the ADMM of Pinocchio's NCP mode (its iteration,
// spectral rho rule and proximal term), on the exact projection onto K.
//
// Layout (rows of D, g and the impulses): (t1, t2, n) per contact, Pinocchio's order, then one row per contact whose
// torsion is > 0, in contact order.
#pragma once

#include <Eigen/Core>

#include "cone_solve.hpp"

namespace pinstab {

// The nearest point of x (t1, t2, n, tau) to K = {|t| <= mu n, |tau| <= torsion n} (tau ignored, 0 out, for torsion 0).
Eigen::Vector4d torsion_projection(const Eigen::Vector4d& x, double mu, double torsion);

// ncp_residual (cpp/cone_solve.hpp) of the layout above: the natural map of the law with the torsion rows, the largest
// contact's |lambda - P_K(lambda - rho s)| / rho, s the De Saxce velocity, rho = 1 / trace D [units of g]; 0 exactly
// at a solution, infinite for non-finite impulses. Without torsion rows, ncp_residual itself, to the bit.
double torsion_residual(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& impulses,
                        const Eigen::VectorXd& mus, const Eigen::VectorXd& torsions);

// The impulses of the problem (D, g) with friction coefficients mus [-] and torsion lengths torsions [m] (k each, the
// layout above): ADMM (Pinocchio's NCP-mode iteration: tau 0.5, proximal 1e-6, spectral rho rule) on the problem with
// each row scaled to a unit diagonal and steep cones (mu or torsion > 1 once scaled) scaled to 1, until the residual
// (torsion_residual) is within `tolerance` of the velocity scale or `max_iterations`; status: method "ADMM-torsion",
// its iterations and last primal and dual feasibility and complementarity (the check is the caller's).
Eigen::VectorXd torsion_admm(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& mus,
                             const Eigen::VectorXd& torsions, double tolerance, int max_iterations,
                             ConeStatus& status);

}  // namespace pinstab
