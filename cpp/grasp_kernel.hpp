// pinstab.paths.grasp.GraspDynamics compiled: sticking fingertip contacts (point rows), hold torques and constant
// wrenches, with the Baumgarte corrector, solved through Cholesky factors (docs/mathematics.md section 4).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "kernels.hpp"

namespace pinstab {

// A fingertip contact's point rows: the components (of x, y, z in C) it keeps, its friction coefficient (the
// tangential check when it keeps x and y).
struct FingertipSpec {
  int object_frame, finger_frame;
  std::vector<int> components;
  double mu;
};

// A contact's columns in a hold's stacked forces: the normal's, the tangents' (-1: frictionless) and mu.
struct ConeSpec {
  int normal, tangent1, tangent2;
  double mu;
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

// One evaluation: M a + h = tau + wrenches + holds + G^T lambda, G a = -gamma0 - Kd G v - Kp phi. Not to be used
// (false) where the general path would leave the direct solve (M or the Delassus matrix not safely positive
// definite), a hold's least-squares forces leave a cone or the cap (its QP takes them), a contact's multipliers
// leave its cone (the general path names it) or a result is not finite.
class GraspKernel : public Kernel {
 public:
  GraspKernel(const pinocchio::Model& model, std::vector<FingertipSpec> contacts, std::vector<HoldSpec> holds,
              std::vector<WrenchSpec> wrenches, double kp, double kd, double direct_pivot, double margin_slack);
  bool acceleration(double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, VectorXd& a) override;
  int nv() const override { return model_.nv; }
  const VectorXd& multipliers() const { return multipliers_; }
  // the largest relative |G a - rhs| of the evaluations used (pinstab.solvers.base.primal_residual)
  double worst_residual() const { return worst_residual_; }

 private:
  bool hold_torques(const HoldSpec& hold, const VectorXd& q, const VectorXd& v, VectorXd& force);
  static bool closest_solution(const HoldSpec& hold, const Eigen::MatrixXd& matrix, const VectorXd& rhs, VectorXd& x);
  static bool holds(const HoldSpec& hold, const VectorXd& forces);
  bool inside_cones() const;

  pinocchio::Model model_;
  pinocchio::Data data_;
  std::vector<FingertipSpec> contacts_;
  std::vector<HoldSpec> holds_;
  std::vector<WrenchSpec> wrenches_;
  double kp_, kd_;
  double direct_pivot_;  // the Delassus matrix's smallest pivot^2 over its largest diagonal entry (solvers.proxsuite_)
  double margin_slack_;  // the contact check's slack (contact.models.MARGIN_SLACK)
  int rows_;
  double worst_residual_;
  Eigen::MatrixXd jacobian_, spread_, delassus_, frame_jacobian_;
  VectorXd phi_, drift_, force_, free_, multipliers_;
  Eigen::LLT<Eigen::MatrixXd> mass_, inner_;
};

}  // namespace pinstab
