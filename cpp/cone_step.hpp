// The numeric part of a time-stepping contact step (pinstab.integration.contact_stepping.ContactStepper: the
// velocity-level Moreau-Jean step with impulses on exact round cones), compiled: the free velocity with the velocity
// terms at the step's midpoint (fixed point), the contacts whose gap closes within the step, their normal biases
// (gap / dt, Newton's impact law), the Delassus matrix, the checked cone solve (cpp/cone_solve.hpp), the impulses'
// velocity change and the position update with free flyers stepped in their parent's axes. What stays in Python: the
// contacts (found by coal, their gaps and Jacobians: pinstab.solvers.contact_modes, shared with event-driven
// contacts), the applied forces, and the modes and events read from the step's impulses.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include "cone_solve.hpp"

namespace pinstab {

// The contacts of a step at its start (k of them, rows (n, t1, t2) each in the contact's basis): gaps [m], normal
// velocities [m/s], Jacobians (3k x nv), friction coefficients [-] and restitutions [-]; torsion lengths [m] (k: 0 for
// none) and the rows of the relative angular velocity about the normal of each contact with torsion (s x nv, contact
// order: cpp/torsion_cone.hpp's law).
struct StepContacts {
  Eigen::VectorXd gaps, normal_velocities;
  Eigen::MatrixXd jacobian;
  Eigen::VectorXd mus, restitutions, torsions;
  Eigen::MatrixXd spin_jacobian;
};

// The settings of the step: TOUCH_GAP [m] (a contact is in the problem when gap + dt (J v)_n <= touch_gap, v the free
// velocity or the velocity after the impulses of the contacts already in it: the problem grows until none is added), the
// midpoint's relative tolerance and passes (each pass over the impulses solves the problem again), the cone solve's
// check (relative residual accepted) and the impulses' midpoint tolerance (relative: the free velocity the answer's
// velocity change gives against the one it was solved from).
struct StepSettings {
  double touch_gap = 0.0, midpoint_tolerance = 1e-13;
  int midpoint_passes = 50;
  double check_rtol = 1e-6, impulse_tolerance = 1e-12;
};

// What a step computed: the end state (q+, v+: free flyers' linear velocity in their joint frame at q+), the contacts
// in the problem, the impulses (k x 3) [N s] and the contact velocities J v+ (k x 3) [m/s], each in (n, t1, t2), the
// normal velocity a unit normal impulse gives each contact [m/s / N s], the torsions' torque impulses [N m s] and spin
// velocities [rad/s] (s each); settled false: the midpoint's passes did not settle (the rest not set); solved false: no
// solver met the contact law (the end state not set).
struct StepResult {
  Eigen::VectorXd q, v;
  std::vector<int> active;
  Eigen::MatrixXd impulses, velocities;
  Eigen::VectorXd reach, torques, spins;
  bool settled = true, solved = true;
};

// The free-flyer joints of a model, stepped in their parent's axes (pdot = R v_lin as MuJoCo's free joints): the
// turn -omega x v_lin of their translation rows that keeps pdot constant, and the position update p+ = p + dt R v_lin
// with the stored v_lin = R+^T R v_lin (the same pdot in the end's joint frame).
class FreeFlyers {
 public:
  explicit FreeFlyers(const pinocchio::Model& model);
  // the generalized acceleration [m/s^2, rad/s^2] that keeps each free flyer's pdot constant at the velocity v
  Eigen::VectorXd turn(const Eigen::VectorXd& v) const;
  // q (+) dt v with each free flyer moved by dt pdot and turned by dt omega: (q+, v+) into q_next, v_next
  void integrate(const pinocchio::Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& v, double dt,
                 Eigen::VectorXd& q_next, Eigen::VectorXd& v_next) const;

 private:
  std::vector<std::pair<int, int>> joints_;  // (idx_q, idx_v)
};

// One step of dt [s] from (q, v): M (nv x nv) [kg, kg m^2] and force = tau - h(q, v) [N, N m] at the step's start,
// the model's Data for the velocity terms (nonLinearEffects at the midpoint velocity), the contacts, a guess of the
// impulses (3k + s, the contacts' rows then the torsions': the last step's [N s, N m s]) for the first midpoint, the
// solver.
StepResult cone_step(const pinocchio::Model& model, pinocchio::Data& data, const FreeFlyers& free_flyers,
                     const Eigen::VectorXd& q, const Eigen::VectorXd& v, double dt, const Eigen::MatrixXd& mass,
                     const Eigen::VectorXd& force, const StepContacts& contacts, const Eigen::VectorXd& guess,
                     const StepSettings& settings, ConeSolver& solver);

}  // namespace pinstab
