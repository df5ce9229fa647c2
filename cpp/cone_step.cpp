#include "cone_step.hpp"

#include <algorithm>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea.hpp>

namespace pinstab {

namespace {

constexpr int CONE_ROWS[3] = {1, 2, 0};  // Pinocchio's rows (t1, t2, n) as indices of pinstab's (n, t1, t2)

double largest(const Eigen::VectorXd& x) { return x.size() ? x.cwiseAbs().maxCoeff() : 0.0; }

// b_n of a contact [m/s]: the gap's term gap / dt, or Newton's impact law min(gap / dt, e v_n) when it approaches
// (v_n < 0) with restitution e > 0.
double normal_bias(double gap, double normal_velocity, double restitution, double dt) {
  double bias = gap / dt;
  if (restitution > 0.0 && normal_velocity < 0.0) bias = std::min(bias, restitution * normal_velocity);
  return bias;
}

// The free velocity v + dt (M^-1 (force - c(w)) - turn(w)) [m/s, rad/s], the velocity terms c (gravity cancels in the
// difference of h at w and at v) and the free flyers' turn taken at the midpoint w = (v + v_free + change) / 2 of the
// step's velocities (`change`: the impulses' velocity change), by fixed point from `v_free`; false: the passes did not
// settle.
bool free_velocity(const pinocchio::Model& model, pinocchio::Data& data, const FreeFlyers& free_flyers,
                   const Eigen::VectorXd& q, const Eigen::VectorXd& v, double dt,
                   const Eigen::LLT<Eigen::MatrixXd>& factor, const Eigen::VectorXd& force,
                   const Eigen::VectorXd& at_start, const Eigen::VectorXd& change, const StepSettings& settings,
                   Eigen::VectorXd& v_free) {
  for (int pass = 0; pass < settings.midpoint_passes; ++pass) {
    const Eigen::VectorXd middle = 0.5 * (v + v_free + change);
    const Eigen::VectorXd shift = pinocchio::nonLinearEffects(model, data, q, middle) - at_start;
    const Eigen::VectorXd next = v + dt * (factor.solve(force - shift) - free_flyers.turn(middle));
    const double moved = largest(next - v_free);
    v_free = next;
    if (moved <= settings.midpoint_tolerance * largest(v_free)) return true;
  }
  return false;
}

}  // namespace

FreeFlyers::FreeFlyers(const pinocchio::Model& model) {
  for (std::size_t j = 1; j < model.joints.size(); ++j) {
    if (model.joints[j].shortname() == "JointModelFreeFlyer") joints_.emplace_back(model.idx_qs[j], model.idx_vs[j]);
  }
}

Eigen::VectorXd FreeFlyers::turn(const Eigen::VectorXd& v) const {
  Eigen::VectorXd shift = Eigen::VectorXd::Zero(v.size());
  for (const auto& [iq, iv] : joints_) {
    const Eigen::Vector3d linear = v.segment<3>(iv), omega = v.segment<3>(iv + 3);
    shift.segment<3>(iv) = -omega.cross(linear);
  }
  return shift;
}

void FreeFlyers::integrate(const pinocchio::Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                           double dt, Eigen::VectorXd& q_next, Eigen::VectorXd& v_next) const {
  q_next = pinocchio::integrate(model, q, (dt * v).eval());
  v_next = v;
  for (const auto& [iq, iv] : joints_) {
    const Eigen::Matrix3d rotation = Eigen::Map<const Eigen::Quaterniond>(q.data() + iq + 3).toRotationMatrix();
    const Eigen::Vector3d rate = rotation * v.segment<3>(iv);
    q_next.segment<3>(iq) = q.segment<3>(iq) + dt * rate;
    const Eigen::Matrix3d turned = Eigen::Map<const Eigen::Quaterniond>(q_next.data() + iq + 3).toRotationMatrix();
    v_next.segment<3>(iv) = turned.transpose() * rate;
  }
}

StepResult cone_step(const pinocchio::Model& model, pinocchio::Data& data, const FreeFlyers& free_flyers,
                     const Eigen::VectorXd& q, const Eigen::VectorXd& v, double dt, const Eigen::MatrixXd& mass,
                     const Eigen::VectorXd& force, const StepContacts& contacts, const Eigen::VectorXd& guess,
                     const StepSettings& settings, ConeSolver& solver) {
  StepResult result;
  const Eigen::LLT<Eigen::MatrixXd> factor(mass);
  const Eigen::VectorXd at_start = pinocchio::nonLinearEffects(model, data, q, v);
  const Eigen::Index k = contacts.gaps.size(), spins = contacts.spin_jacobian.rows();
  Eigen::MatrixXd stacked(3 * k + spins, spins ? model.nv : 0);  // the contacts' rows, then the torsions'
  if (spins) stacked << contacts.jacobian, contacts.spin_jacobian;
  const Eigen::MatrixXd& jacobian = spins ? stacked : contacts.jacobian;
  const Eigen::MatrixXd mobility = factor.solve(jacobian.transpose());  // M^-1 J^T
  Eigen::VectorXd v_free, reach;
  // the problem's contacts: those the free motion closes, then those the impulses of the others close (a body pressed
  // onto one that its contact stops), solved again with them until none is added (at most k solves); a grown problem
  // whose answer no solver finds is given up for the one before it (solved again: the solver's status is its answer's)
  std::vector<char> in_problem(static_cast<std::size_t>(k), 0);
  const auto admit = [&](const Eigen::VectorXd& velocity) {
    bool grown = false;
    for (Eigen::Index i = 0; i < k; ++i) {
      if (in_problem[i] || contacts.gaps(i) + dt * velocity(3 * i) > settings.touch_gap) continue;
      in_problem[i] = 1;
      grown = true;
    }
    return grown;
  };
  Eigen::VectorXd v_new;
  const auto solve = [&]() {
    result.active.clear();
    for (Eigen::Index i = 0; i < k; ++i) {
      if (in_problem[i]) result.active.push_back(static_cast<int>(i));
    }
    result.impulses = Eigen::MatrixXd::Zero(k, 3);
    result.torques = Eigen::VectorXd::Zero(spins);
    v_new = v_free;
    if (result.active.empty()) return true;
    std::vector<Eigen::Index> rows, torsion_rows;
    for (const int i : result.active) {
      for (const int r : CONE_ROWS) rows.push_back(3 * i + r);
    }
    Eigen::VectorXd torsions = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(result.active.size()));
    for (std::size_t a = 0; a < result.active.size(); ++a) {  // each torsion's row after the contacts'
      const int i = result.active[a];
      if (contacts.torsions(i) <= 0.0) continue;
      torsions(static_cast<Eigen::Index>(a)) = contacts.torsions(i);
      torsion_rows.push_back(3 * k + (contacts.torsions.head(i).array() > 0.0).count());
      rows.push_back(torsion_rows.back());
    }
    const Eigen::Index m = static_cast<Eigen::Index>(rows.size());
    Eigen::MatrixXd delassus(m, m), active_jacobian(m, jacobian.cols()), active_mobility(jacobian.cols(), m);
    Eigen::VectorXd g(m), mus(result.active.size());
    for (Eigen::Index a = 0; a < m; ++a) {
      active_jacobian.row(a) = jacobian.row(rows[a]);
      active_mobility.col(a) = mobility.col(rows[a]);
      g(a) = reach(rows[a]);
    }
    for (std::size_t a = 0; a < result.active.size(); ++a) {
      const int i = result.active[a];
      mus(a) = contacts.mus(i);
      g(3 * a + 2) += normal_bias(contacts.gaps(i), contacts.normal_velocities(i), contacts.restitutions(i), dt);
    }
    delassus.noalias() = active_jacobian * active_mobility;
    const Eigen::VectorXd solution = torsion_rows.empty()
                                         ? solver.solve(delassus, g, mus, settings.check_rtol)
                                         : solver.solve_torsion(delassus, g, mus, torsions, settings.check_rtol);
    for (std::size_t a = 0; a < result.active.size(); ++a) {
      result.impulses.row(result.active[a]) << solution(3 * a + 2), solution(3 * a), solution(3 * a + 1);
    }
    const Eigen::Index linear = 3 * static_cast<Eigen::Index>(result.active.size());
    for (std::size_t j = 0; j < torsion_rows.size(); ++j) {
      result.torques(torsion_rows[j] - 3 * k) = solution(linear + static_cast<Eigen::Index>(j));
    }
    if (!solver.status().converged) return false;
    v_new += active_mobility * solution;
    return true;
  };
  // the problem's answer from the free velocity v_free: the contacts the free motion closes, grown as above
  const auto contact_solve = [&]() {
    reach = jacobian * v_free;
    std::fill(in_problem.begin(), in_problem.end(), 0);
    admit(reach);
    if (!solve()) return false;
    for (std::vector<char> before = in_problem; admit(jacobian * v_new); before = in_problem) {
      if (!solve()) {
        in_problem = before;
        return solve();
      }
    }
    return true;
  };
  // the velocity terms at the midpoint of the step's velocities, v and v+ = v_free + M^-1 J^T lambda: the impulses'
  // change first taken from `guess` (the last step's impulses of these contacts), then from the answer, until the
  // free velocity that the answer's change gives moves by at most impulse_tolerance of the velocities
  Eigen::VectorXd change = mobility * guess;
  Eigen::VectorXd next = v + dt * (factor.solve(force) - free_flyers.turn(v));  // each fixed point from the last
  for (int pass = 0;; ++pass) {
    v_free = next;
    result.settled = pass < settings.midpoint_passes &&
                     free_velocity(model, data, free_flyers, q, v, dt, factor, force, at_start, change, settings,
                                   v_free);
    if (!result.settled) return result;
    result.solved = contact_solve();
    if (!result.solved) return result;
    const Eigen::VectorXd found = v_new - v_free;
    if (found == change) break;  // the midpoint it was solved from (no impulse, or the guess's): its fixed point
    change = found;
    next = v_free;
    result.settled = free_velocity(model, data, free_flyers, q, v, dt, factor, force, at_start, change, settings,
                                   next);
    if (!result.settled) return result;
    if (largest(next - v_free) <= settings.impulse_tolerance * std::max(largest(v_free), largest(v_new))) break;
  }
  const Eigen::VectorXd velocities = jacobian * v_new;
  result.velocities = velocities.head(3 * k).reshaped(3, k).transpose();
  result.spins = velocities.tail(spins);
  result.reach.resize(k);
  for (Eigen::Index i = 0; i < k; ++i) result.reach(i) = jacobian.row(3 * i).dot(mobility.col(3 * i));
  free_flyers.integrate(model, q, v_new, dt, result.q, result.v);
  return result;
}

}  // namespace pinstab
