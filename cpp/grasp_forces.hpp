// Compiled force elements of grasps (pinstab.grasp.hold.GraspHold, pinstab.forces.external_force.ExternalForce) and
// the limits of fingertip contacts (pinstab.contact.models.ContactLimits), for the core kernel and for Python alike.
#pragma once

#include <vector>

#include "kernels.hpp"

namespace pinstab {

// A contact's columns in stacked forces: the normal's, the tangents' (-1: frictionless), the spin moment's (-1: not a
// soft finger), its friction coefficient mu [-] and torsion coefficient [m].
struct ConeSpec {
  int normal, tangent1, tangent2, spin;
  double mu, torsion;
};

// pinstab.grasp.hold.GraspHold: the forces closest to the squeeze that carry the object's weight (least squares),
// and the hand's torques that balance them, with stiffness about q_start and damping.
struct HoldSpec {
  VectorXi rows;            // the hold's contacts' rows in the stacked G
  VectorXi object_columns;  // the object's velocity indices
  VectorXi hand_columns;    // the others
  VectorXd pressing;        // the squeeze along each normal [N]
  std::vector<ConeSpec> cones;
  VectorXd q_start;
  double stiffness, damping, cap;  // [N m/rad], [N m s/rad], [N] (inf: none)
  // the cone test's slack relative to the largest force (grasp.holding.FEASIBILITY), the least squares' rank
  // tolerance and largest condition of the normal equations (grasp.linalg)
  double feasibility, rank, condition;
};

// A constant wrench (force, moment) [N, N m] in world axes at a frame.
struct WrenchSpec {
  int frame;
  Eigen::Matrix<double, 6, 1> wrench;
};

// Adds a hold's torques at (q, v) to force, from the stacked constraint Jacobian and data.g (a full pass); false where
// its least-squares forces leave a cone or the cap (the hold's QP takes them: the evaluation is not to be used).
bool add_hold_torques(const pinocchio::Model& model, const pinocchio::Data& data, const HoldSpec& hold,
                      const Eigen::MatrixXd& jacobian, const VectorXd& q, const VectorXd& v, Eigen::Ref<VectorXd> force);
// pinstab.grasp.hold.GraspHold.torques (which calls it): adds, on each hand column c, the torque that makes the held
// forces an equilibrium of the hand, g[c] - sum_k G(rows_k, c) forces_k - stiffness deviation[c] - damping v[c]
// [N m] (G: the stacked constraint Jacobian, rows: the hold's contacts' rows in it, deviation: q_start to q).
void add_hold_balance(const Eigen::MatrixXd& jacobian, const VectorXi& rows, const VectorXi& hand_columns,
                      const VectorXd& gravity, const VectorXd& forces, const VectorXd& deviation, const VectorXd& v,
                      double stiffness, double damping, Eigen::Ref<VectorXd> force);
// Adds J^T w of a constant world wrench at its frame (Jacobians current) to force.
void add_wrench(const pinocchio::Model& model, pinocchio::Data& data, const WrenchSpec& wrench,
                Eigen::Ref<VectorXd> force);
// pinstab.grasp.linalg.closest_solution: target + A^+ (rhs - A target), through the Cholesky factor of A A^T where
// its condition allows (condition), else the SVD with singular values under rank max(1, the largest) dropped.
bool closest_solution(const Eigen::MatrixXd& matrix, const VectorXd& rhs, const VectorXd& target, double rank,
                      double condition, VectorXd& x);
// pinstab.grasp.holding.ConeTest.holds (which calls it): every force finite, every contact's normal force >= 0,
// inside its friction cone (|f_t| <= mu f_n) and torsion limit (|m_z| <= torsion f_n), beyond a slack of feasibility
// (1 + the largest |force|), and its normal force at most cap (1 + 1e-9) (inf: no cap).
bool cones_hold(const std::vector<ConeSpec>& cones, double cap, double feasibility, const VectorXd& forces);

// A fingertip contact's contact model (pinstab.contact.models.WRENCH_BASES): what it can carry.
enum class ContactModel { frictionless = 0, point_friction = 1, soft_finger = 2, rigid = 3 };
// (normal f_n [N], friction mu f_n - |f_t| [N], torsion torsion f_n - |m_z| [N m]) of a wrench (fx, fy, fz, mx, my,
// mz in the contact frame): +inf where the model has no such limit (a rigid contact has none).
Eigen::Vector3d contact_margins(ContactModel model, double mu, double torsion, const Eigen::Matrix<double, 6, 1>& wrench);
// Whether every margin is above -slack (1 + the largest |component|).
bool contact_holds(ContactModel model, double mu, double torsion, const Eigen::Matrix<double, 6, 1>& wrench,
                   double slack);

}  // namespace pinstab
