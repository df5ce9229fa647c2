#include "torsion_cone.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace pinstab {

namespace {

// ADMM's constants, Pinocchio's defaults (ADMMSolverSettings): the step's share tau of rho, the proximal term, the
// spectral rule's initial power and its increment's power, the primal/dual imbalance that changes rho, rho's range.
constexpr double TAU = 0.5, PROXIMAL = 1e-6, RHO_POWER = 0.2, RHO_POWER_FACTOR = 0.05, RATIO = 10.0;
constexpr double RHO_MIN = 1e-6, RHO_MAX = 1e6;

// The row of each contact's torsion (-1: none) in the layout of torsion_cone.hpp.
std::vector<Eigen::Index> torsion_rows(const Eigen::VectorXd& torsions) {
  std::vector<Eigen::Index> rows(static_cast<std::size_t>(torsions.size()), -1);
  Eigen::Index next = 3 * torsions.size();
  for (Eigen::Index i = 0; i < torsions.size(); ++i) {
    if (torsions(i) > 0.0) rows[static_cast<std::size_t>(i)] = next++;
  }
  return rows;
}

// Contact i's (t1, t2, n, tau) of a vector of the layout (tau 0 without a torsion row), and back.
Eigen::Vector4d gather(const Eigen::VectorXd& x, Eigen::Index i, Eigen::Index spin) {
  return Eigen::Vector4d(x(3 * i), x(3 * i + 1), x(3 * i + 2), spin >= 0 ? x(spin) : 0.0);
}

void scatter(const Eigen::Vector4d& part, Eigen::Index i, Eigen::Index spin, Eigen::VectorXd& x) {
  x.segment<3>(3 * i) = part.head<3>();
  if (spin >= 0) x(spin) = part(3);
}

// P_K of every contact of a vector of the layout.
Eigen::VectorXd project(const Eigen::VectorXd& x, const Eigen::VectorXd& mus, const Eigen::VectorXd& torsions,
                        const std::vector<Eigen::Index>& spins) {
  Eigen::VectorXd out(x.size());
  for (Eigen::Index i = 0; i < mus.size(); ++i) {
    const Eigen::Index spin = spins[static_cast<std::size_t>(i)];
    scatter(torsion_projection(gather(x, i, spin), mus(i), torsions(i)), i, spin, out);
  }
  return out;
}

// The De Saxce velocity of contact velocities sigma (layout): each normal row + mu |sigma_t| + torsion |sigma_tau|.
Eigen::VectorXd desaxce(const Eigen::VectorXd& sigma, const Eigen::VectorXd& mus, const Eigen::VectorXd& torsions,
                        const std::vector<Eigen::Index>& spins) {
  Eigen::VectorXd out = sigma;
  for (Eigen::Index i = 0; i < mus.size(); ++i) {
    const Eigen::Index spin = spins[static_cast<std::size_t>(i)];
    const double spin_speed = spin >= 0 ? std::abs(sigma(spin)) : 0.0;
    out(3 * i + 2) += mus(i) * std::hypot(sigma(3 * i), sigma(3 * i + 1)) + torsions(i) * spin_speed;
  }
  return out;
}

// The scales s of the rows (lambda = s lambda'): each row to a unit diagonal of D (a common one for a contact's
// tangents), the cones steeper than 1 once scaled to 1 by their friction rows (as cone_solve.cpp's max(mu, 1)); the
// scaled mu and torsion into mus_out and torsions_out.
Eigen::VectorXd row_scales(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& mus, const Eigen::VectorXd& torsions,
                           const std::vector<Eigen::Index>& spins, Eigen::VectorXd& mus_out,
                           Eigen::VectorXd& torsions_out) {
  const auto unit = [&](Eigen::Index a, Eigen::Index b) {
    const double diagonal = 0.5 * (delassus(a, a) + delassus(b, b));
    return diagonal > 0.0 ? 1.0 / std::sqrt(diagonal) : 1.0;
  };
  Eigen::VectorXd scales = Eigen::VectorXd::Ones(delassus.rows());
  mus_out = mus;
  torsions_out = torsions;
  for (Eigen::Index i = 0; i < mus.size(); ++i) {
    const double normal = unit(3 * i + 2, 3 * i + 2);
    double tangent = unit(3 * i, 3 * i + 1);
    mus_out(i) = mus(i) * normal / tangent;
    if (mus_out(i) > 1.0) tangent *= mus_out(i), mus_out(i) = 1.0;
    scales.segment<3>(3 * i) << tangent, tangent, normal;
    const Eigen::Index spin = spins[static_cast<std::size_t>(i)];
    if (spin < 0) continue;
    double turn = unit(spin, spin);
    torsions_out(i) = torsions(i) * normal / turn;
    if (torsions_out(i) > 1.0) turn *= torsions_out(i), torsions_out(i) = 1.0;
    scales(spin) = turn;
  }
  return scales;
}

}  // namespace

Eigen::Vector4d torsion_projection(const Eigen::Vector4d& x, double mu, double torsion) {
  const double tangential = std::hypot(x(0), x(1)), normal = x(2);
  const double spin = torsion > 0.0 ? std::abs(x(3)) : 0.0;
  Eigen::Vector4d out(x(0), x(1), x(2), torsion > 0.0 ? x(3) : 0.0);
  if (tangential <= mu * normal && spin <= torsion * normal && normal >= 0.0) return out;
  // n minimizes (n - normal)^2 + (tangential - mu n)_+^2 + (spin - torsion n)_+^2 over n >= 0: the root of its
  // increasing slope, each friction's term active (the friction cut to its bound) below its breakpoint
  const double inf = std::numeric_limits<double>::infinity();
  const double slip_break = mu > 0.0 ? tangential / mu : inf, spin_break = torsion > 0.0 ? spin / torsion : inf;
  const auto slope = [&](double n) {
    return n - normal - mu * std::max(tangential - mu * n, 0.0) - torsion * std::max(spin - torsion * n, 0.0);
  };
  const double first = std::min(slip_break, spin_break), second = std::max(slip_break, spin_break);
  bool slip_cut = true, spin_cut = true;  // the root below both breakpoints
  if (first < inf && slope(first) < 0.0) {
    (first == slip_break ? slip_cut : spin_cut) = false;
    if (second < inf && slope(second) < 0.0) slip_cut = spin_cut = false;
  }
  const double pull = normal + (slip_cut ? mu * tangential : 0.0) + (spin_cut ? torsion * spin : 0.0);
  const double along = std::max(pull, 0.0) / (1.0 + (slip_cut ? mu * mu : 0.0) + (spin_cut ? torsion * torsion : 0.0));
  const double shrink = !slip_cut ? 1.0 : tangential > 0.0 ? mu * along / tangential : 0.0;
  out << x(0) * shrink, x(1) * shrink, along, spin_cut ? std::copysign(torsion * along, out(3)) : out(3);
  return out;
}

double torsion_residual(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& impulses,
                        const Eigen::VectorXd& mus, const Eigen::VectorXd& torsions) {
  if (!impulses.allFinite()) return std::numeric_limits<double>::infinity();
  const double rho = 1.0 / std::max(delassus.trace(), std::numeric_limits<double>::min());
  const std::vector<Eigen::Index> spins = torsion_rows(torsions);
  const Eigen::VectorXd velocity = desaxce(delassus * impulses + g, mus, torsions, spins);
  double worst = 0.0;
  for (Eigen::Index i = 0; i < mus.size(); ++i) {
    const Eigen::Index spin = spins[static_cast<std::size_t>(i)];
    const Eigen::Vector4d lambda = gather(impulses, i, spin);
    const Eigen::Vector4d gap =
        lambda - torsion_projection(lambda - rho * gather(velocity, i, spin), mus(i), torsions(i));
    worst = std::max(worst, spin >= 0 ? gap.norm() : gap.head<3>().norm());
  }
  return worst / rho;
}

Eigen::VectorXd torsion_admm(const Eigen::MatrixXd& delassus, const Eigen::VectorXd& g, const Eigen::VectorXd& mus,
                             const Eigen::VectorXd& torsions, double tolerance, int max_iterations,
                             ConeStatus& status) {
  const std::vector<Eigen::Index> spins = torsion_rows(torsions);
  Eigen::VectorXd mus_scaled, torsions_scaled;
  const Eigen::VectorXd scales = row_scales(delassus, mus, torsions, spins, mus_scaled, torsions_scaled);
  const Eigen::MatrixXd scaled = scales.asDiagonal() * delassus * scales.asDiagonal();
  const Eigen::MatrixXd G = 0.5 * (scaled + scaled.transpose());
  const Eigen::VectorXd gs = scales.cwiseProduct(g);
  const Eigen::Index m = g.size();
  const double largest = std::max(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(G, Eigen::EigenvaluesOnly)
                                      .eigenvalues()
                                      .maxCoeff(),
                                  2.0 * PROXIMAL);
  const double increment = std::pow(largest / PROXIMAL, RHO_POWER_FACTOR);
  double rho = std::clamp(std::sqrt(largest * PROXIMAL) * std::pow(largest / PROXIMAL, RHO_POWER), RHO_MIN, RHO_MAX);
  const Eigen::MatrixXd identity = Eigen::MatrixXd::Identity(m, m);
  Eigen::LLT<Eigen::MatrixXd> factor(G + (TAU * rho + PROXIMAL) * identity);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m), y = x, z = desaxce(gs, mus_scaled, torsions_scaled, spins);
  Eigen::VectorXd impulses = Eigen::VectorXd::Zero(m);
  const double velocity_scale = g.size() ? g.cwiseAbs().maxCoeff() : 0.0;
  status = ConeStatus();
  status.method = "ADMM-torsion";
  for (status.iterations = 1; status.iterations <= max_iterations; ++status.iterations) {
    const Eigen::VectorXd x_previous = x, z_previous = z;
    y = project(x - z / (TAU * rho), mus_scaled, torsions_scaled, spins);
    const Eigen::VectorXd correction = desaxce(z_previous, mus_scaled, torsions_scaled, spins) - z_previous;
    x = factor.solve(-(gs + correction - (TAU * rho) * y - PROXIMAL * x_previous - z_previous));
    z = z_previous - (TAU * rho) * (x - y);
    status.primal_feasibility = (x - y).cwiseAbs().maxCoeff();
    status.dual_feasibility = std::max(PROXIMAL, TAU * rho) * (x - x_previous).cwiseAbs().maxCoeff();
    impulses = scales.cwiseProduct(y);
    const double scale = std::max(velocity_scale, (delassus * impulses).cwiseAbs().maxCoeff());
    if (torsion_residual(delassus, g, impulses, mus, torsions) <= tolerance * scale) break;
    double next = rho;
    if (status.primal_feasibility > RATIO * status.dual_feasibility) next *= increment;
    else if (status.dual_feasibility > RATIO * status.primal_feasibility) next /= increment;
    next = std::clamp(next, RHO_MIN, RHO_MAX);
    if (next != rho) {
      rho = next;
      factor.compute(G + (TAU * rho + PROXIMAL) * identity);
    }
  }
  status.iterations = std::min(status.iterations, static_cast<long>(max_iterations));
  for (Eigen::Index i = 0; i < mus.size(); ++i) {
    const Eigen::Index spin = spins[static_cast<std::size_t>(i)];
    status.complementarity = std::max(status.complementarity, std::abs(gather(y, i, spin).dot(gather(z, i, spin))));
  }
  return impulses;
}

}  // namespace pinstab
