// Plane contacts in given modes, the core kernel's form of pinstab.solvers.contact_modes.ModeDynamics (its module
// docstring states the rules): contact i is a point of a body (a sphere's centre, radius r) on a plane fixed in the
// world or carried by a body, basis B_i with rows (n, t1, t2); its rows B_i (J_i a + c_i) are cpp/plane_contacts.hpp's. The bilateral rows
// (closures, held one-row entries) are eliminated first through the rank-revealing factorization of their Jacobian
// (not the Delassus matrix, whose condition squares theirs: Cassie's shin-spring triangles, 2e-7 from singular), then
// the 3k x 3k force system of the modes is solved: sticking B_i (J_i a + c_i) = 0; sliding n.(J_i a + c_i) = 0 and
// f_t + mu f_n d = 0 (d the unit slip, SLIP_FLOOR's rule); separated f_i = 0.
#pragma once

#include <map>
#include <vector>

#include <Eigen/Dense>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include "kernels.hpp"
#include "plane_contacts.hpp"

namespace pinstab {

// pinstab.contact.modes.Mode
enum class ContactMode { sticking = 0, sliding = 1, separated = 2 };

// The settings: relative singular values below held_rank drop a bilateral row (HELD_RANK_TOLERANCE), below
// rank_tolerance a force row (RANK_TOLERANCE); slips slower than slip_floor [m/s] keep their direction (SLIP_FLOOR); a
// sliding contact with friction slower than grazing_speed [m/s] (GRAZING_SPEED) is not solved here: ModeDynamics may
// slave its direction to its slip acceleration (a grazing slip).
struct ContactSettings {
  double held_rank = 1e-9, rank_tolerance = 1e-12, slip_floor = 1e-9, grazing_speed = 1e-5;
};

// The unit slip direction (pinstab.solvers.contact_modes.unit_slip): `reference` once the slip has turned against it
// (when `continued`), else slip / |slip|, or `fallback` while |slip| <= floor.
Eigen::Vector2d unit_slip(const Eigen::Vector2d& slip, const Eigen::Vector2d& fallback,
                          const Eigen::Vector2d& reference, bool continued, double floor);

class ContactModes {
 public:
  // the contacts (cpp/plane_contacts.hpp) and their friction coefficients mu [-]
  ContactModes(std::vector<PlaneContact> contacts, VectorXd mus, ContactSettings settings);
  // The modes (k), each contact's fallback slip direction (k x 2, in (t1, t2)) and, where `continued`, the direction
  // a continued slip keeps once it turns against it (k x 2).
  void set_modes(const std::vector<ContactMode>& modes, const Eigen::MatrixXd& directions,
                 const Eigen::MatrixXd& references, const Mask& continued);
  // The accelerations at the state of `data` (after computeAllTerms and updateFramePlacements at (q, v)): M (both
  // triangles), force = tau - h [N, N m], the bilateral rows B (b x nv) held at B a = target; false: not solved (a
  // singular reduced mass, a gap or force not finite: ModeDynamics names it; a grazing slip: ModeDynamics solves it).
  bool solve(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& v, const Eigen::MatrixXd& mass,
             const VectorXd& force, const Eigen::MatrixXd& rows, const VectorXd& target);

  int size() const { return static_cast<int>(contacts_.size()); }
  // the last solve's: accelerations, contact forces (k x 3, basis), accelerations without contact forces and their
  // response (nv x 3k), the bilateral reactions (b), the contacts' rows (cpp/plane_contacts.hpp: gaps, points,
  // velocities, Jacobian, drift), the force system's relative residual
  const VectorXd& acceleration() const { return acceleration_; }
  Eigen::MatrixXd forces() const;
  const VectorXd& free() const { return free_; }
  const Eigen::MatrixXd& mobility() const { return mobility_; }
  const VectorXd& reactions() const { return reactions_; }
  const PlaneContactRows& rows() const { return rows_; }
  double residual() const { return residual_; }

 private:
  bool kinematics(const pinocchio::Model& model, pinocchio::Data& data, const VectorXd& v);
  bool held(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& rows, const Eigen::MatrixXd& columns,
            const VectorXd& target, Eigen::MatrixXd& response, Eigen::MatrixXd& reactions) const;
  bool forces_of(const Eigen::MatrixXd& system, const VectorXd& rhs);

  std::vector<PlaneContact> contacts_;
  VectorXd mus_;
  ContactSettings settings_;
  std::vector<ContactMode> modes_;
  Eigen::MatrixXd directions_, references_;
  Mask continued_;
  std::map<std::vector<int>, bool> redundant_;  // by the modes: whether the force system is rank-deficient
  PlaneContactRows rows_;
  Eigen::MatrixXd jacobian_, mobility_;  // rows_.jacobian, column-major
  VectorXd free_, reactions_, acceleration_, forces_;
  double residual_ = 0.0;
};

}  // namespace pinstab
