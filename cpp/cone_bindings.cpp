// pinstab._compiled.ConeSolver, ncp_residual, ConeStepper and plane_contact_rows: the checked cone solve of
// pinstab.solvers.ncp, the numeric part of the time-stepping contacts' step (pinstab.integration.contact_stepping) and
// the plane contacts' rows both contact treatments read (pinstab.solvers.contact_modes), cpp/cone_solve.hpp,
// cpp/cone_step.hpp and cpp/plane_contacts.hpp.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <optional>
#include <stdexcept>
#include <string>

#include "cone_step.hpp"
#include "kernels.hpp"
#include "numpy_out.hpp"
#include "plane_contacts.hpp"
#include "torsion_cone.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

// The compiled step over a Python pin.Model and one of its pin.Data (kept alive by the binding).
struct ConeStepper {
  const pinocchio::Model& model;
  pinocchio::Data& data;
  FreeFlyers free_flyers;

  ConeStepper(nb::handle python_model_, nb::handle python_data_)
      : model(python_model(python_model_.ptr())),
        data(python_data(python_data_.ptr(), model)),
        free_flyers(model) {}
};

void check_sizes(const pinocchio::Model& model, const VectorXd& q, const VectorXd& v, const Eigen::MatrixXd& mass,
                 const VectorXd& force, const StepContacts& contacts) {
  const Eigen::Index k = contacts.gaps.size();
  if (q.size() != model.nq || v.size() != model.nv || mass.rows() != model.nv || mass.cols() != model.nv ||
      force.size() != model.nv) {
    throw std::invalid_argument("ConeStepper.step: q, v, mass or force not of the model's sizes (nq, nv)");
  }
  if (contacts.normal_velocities.size() != k || contacts.mus.size() != k || contacts.restitutions.size() != k ||
      contacts.torsions.size() != k || contacts.jacobian.rows() != 3 * k || contacts.jacobian.cols() != model.nv ||
      contacts.spin_jacobian.rows() != (contacts.torsions.array() > 0.0).count() ||
      (contacts.spin_jacobian.rows() && contacts.spin_jacobian.cols() != model.nv)) {
    throw std::invalid_argument(
        "ConeStepper.step: gaps, normal velocities, mus, restitutions, torsions (k), jacobian (3k x nv) and "
        "spin_jacobian (one row per torsion > 0 x nv) disagree");
  }
}

// The torsion lengths of a problem's contacts (k), checked against its rows (3k + one per torsion > 0).
void check_layout(const char* where, const Eigen::MatrixXd& delassus, const VectorXd& g, const VectorXd& mus,
                  const VectorXd& torsions) {
  if (delassus.rows() != g.size() || delassus.cols() != g.size() || torsions.size() != mus.size() ||
      g.size() != 3 * mus.size() + (torsions.array() > 0.0).count()) {
    throw std::invalid_argument(std::string(where) +
                                ": D, g (3k + one row per torsion > 0), mus (k) and torsions (k) disagree");
  }
}

// The plane contacts of the arrays (k entries each; bases 3k x 3, origins k x 3), their frames checked in the model.
std::vector<PlaneContact> plane_contacts(const pinocchio::Model& model, const VectorXi& frames,
                                         const VectorXi& plane_frames, const VectorXd& radii, const RowMatrix& bases,
                                         const RowMatrix& origins) {
  const Eigen::Index k = frames.size();
  if (plane_frames.size() != k || radii.size() != k || bases.rows() != 3 * k || bases.cols() != 3 ||
      origins.rows() != k || origins.cols() != 3) {
    throw std::invalid_argument(
        "plane_contact_rows: frames, plane frames, radii (k), bases (3k x 3) and origins (k x 3) disagree");
  }
  std::vector<PlaneContact> contacts(static_cast<std::size_t>(k));
  for (Eigen::Index i = 0; i < k; ++i) {
    PlaneContact& contact = contacts[static_cast<std::size_t>(i)];
    contact.frame = frames(i), contact.plane_frame = plane_frames(i), contact.radius = radii(i);
    if (contact.frame < 0 || contact.frame >= model.nframes || contact.plane_frame < -1 ||
        contact.plane_frame >= model.nframes) {
      throw std::invalid_argument("plane_contact_rows: a frame outside the model (plane frame -1: the world)");
    }
    contact.basis = bases.middleRows<3>(3 * i);
    contact.origin = origins.row(i).transpose();
  }
  return contacts;
}

}  // namespace

void bind_cones(nb::module_& m) {
  m.def(
      "plane_contact_rows",
      [](nb::handle model, nb::handle data, const VectorXi& frames, const VectorXi& plane_frames,
         const VectorXd& radii, const RowMatrix& bases, const RowMatrix& origins, const VectorXd& v) {
        const pinocchio::Model& native = python_model(model.ptr());
        if (v.size() != native.nv) throw std::invalid_argument("plane_contact_rows: v not of the model's size nv");
        const auto contacts = plane_contacts(native, frames, plane_frames, radii, bases, origins);
        PlaneContactRows r = plane_contact_rows(native, python_data(data.ptr(), native), contacts, v);
        return nb::make_tuple(numpy_out(std::move(r.gaps)), numpy_out(std::move(r.positions)),
                              numpy_out(std::move(r.local)), numpy_out(std::move(r.velocities)),
                              numpy_out(std::move(r.jacobian)), numpy_out(std::move(r.drift)),
                              numpy_out(std::move(r.bases)));
      },
      "model"_a, "data"_a, "frames"_a, "plane_frames"_a, "radii"_a, "bases"_a, "origins"_a, "v"_a,
      "The plane contacts' (gaps [m], points [m, world], points in the plane's axes, velocities (k x 3) [m/s], "
      "Jacobians (3k x nv), drifts (3k) [m/s^2], bases (3k x 3, world axes)) at a pin.Data's state after a full "
      "pass; plane frame -1: the world (pinstab.solvers.contact_modes).");
  m.def(
      "ncp_residual",
      [](const Eigen::MatrixXd& delassus, const VectorXd& g, const VectorXd& impulses, const VectorXd& mus,
         const std::optional<VectorXd>& torsions) {
        const VectorXd lengths = torsions ? *torsions : VectorXd::Zero(mus.size());
        check_layout("ncp_residual", delassus, g, mus, lengths);
        if (impulses.size() != g.size()) throw std::invalid_argument("ncp_residual: impulses not of g's size");
        return torsion_residual(delassus, g, impulses, mus, lengths);
      },
      "delassus"_a, "g"_a, "impulses"_a, "mus"_a, "torsions"_a = nb::none(),
      "The natural map's largest contact residual of impulses (t1, t2, n per contact, then one torque row per torsion "
      "> 0) on the problem (D, g) with friction coefficients mus [-] and torsion lengths [m] (None: none), in the "
      "units of g (pinstab.solvers.ncp.ncp_residual).");
  nb::class_<ConeSolver>(m, "ConeSolver")
      .def(
          "__init__",
          [](ConeSolver* self, int size, double tolerance, int max_iterations, int lanczos_size, int check_every,
             double settled) {
            if (size < 0 || max_iterations < 1 || lanczos_size < 1 || check_every < 1 || !(tolerance > 0.0) ||
                !(settled > 0.0 && settled <= 1.0)) {
              throw std::invalid_argument(
                  "ConeSolver: size >= 0, tolerance > 0, max_iterations, lanczos_size and check_every >= 1, settled "
                  "in (0, 1]");
            }
            new (self) ConeSolver(size, tolerance, max_iterations, lanczos_size, check_every, settled);
          },
          "size"_a, "tolerance"_a, "max_iterations"_a, "lanczos_size"_a, "check_every"_a, "settled"_a)
      .def(
          "solve",
          [](ConeSolver& self, const Eigen::MatrixXd& delassus, const VectorXd& g, const VectorXd& mus,
             double check_rtol) {
            if (delassus.rows() != g.size() || delassus.cols() != g.size() || g.size() != 3 * mus.size()) {
              throw std::invalid_argument("ConeSolver.solve: D (3k x 3k), g (3k) and mus (k) disagree");
            }
            return self.solve(delassus, g, mus, check_rtol);
          },
          "delassus"_a, "g"_a, "mus"_a, "check_rtol"_a,
          "The checked impulses (t1, t2, n per contact) of the problem (D, g) with friction coefficients mus [-].")
      .def(
          "solve_torsion",
          [](ConeSolver& self, const Eigen::MatrixXd& delassus, const VectorXd& g, const VectorXd& mus,
             const VectorXd& torsions, double check_rtol) {
            check_layout("ConeSolver.solve_torsion", delassus, g, mus, torsions);
            return self.solve_torsion(delassus, g, mus, torsions, check_rtol);
          },
          "delassus"_a, "g"_a, "mus"_a, "torsions"_a, "check_rtol"_a,
          "The checked impulses (t1, t2, n per contact, then one torque row per torsion > 0) of the problem (D, g) "
          "with friction coefficients mus [-] and torsion lengths torsions [m] (cpp/torsion_cone.hpp).")
      .def_prop_ro("max_iterations", &ConeSolver::max_iterations)
      .def_prop_ro("status", [](const ConeSolver& self) {
        const ConeStatus& s = self.status();
        return nb::make_tuple(s.method, s.iterations, s.converged, s.primal_feasibility, s.dual_feasibility,
                              s.complementarity, s.residual, s.accepted);
      }, "(method, iterations, converged, primal and dual feasibility, complementarity, residual, accepted).");
  nb::class_<ConeStepper>(m, "ConeStepper")
      .def(nb::init<nb::handle, nb::handle>(), "model"_a, "data"_a, nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>())
      .def(
          "step",
          // (the matrices row-major: NumPy's C order, taken without a conversion through NumPy on every step)
          [](ConeStepper& self, const VectorXd& q, const VectorXd& v, double dt, const RowMatrix& mass_rows,
             const VectorXd& force, const VectorXd& gaps, const VectorXd& normal_velocities,
             const RowMatrix& jacobian, const VectorXd& mus, const VectorXd& restitutions, const VectorXd& torsions,
             const RowMatrix& spin_jacobian, const VectorXd& guess, const VectorXd& settings, ConeSolver& solver) {
            const StepContacts contacts{gaps, normal_velocities, jacobian, mus, restitutions, torsions, spin_jacobian};
            const Eigen::MatrixXd mass = mass_rows;
            check_sizes(self.model, q, v, mass, force, contacts);
            if (settings.size() != 5) throw std::invalid_argument("ConeStepper.step: 5 settings");
            if (guess.size() != contacts.jacobian.rows() + contacts.spin_jacobian.rows()) {
              throw std::invalid_argument("ConeStepper.step: guess is not one impulse per contact row and torsion");
            }
            const StepSettings step_settings{settings(0), settings(1), static_cast<int>(settings(2)), settings(3),
                                             settings(4)};
            StepResult r = cone_step(self.model, self.data, self.free_flyers, q, v, dt, mass, force, contacts, guess,
                                     step_settings, solver);
            return nb::make_tuple(numpy_out(std::move(r.q)), numpy_out(std::move(r.v)), r.active,
                                  numpy_out(std::move(r.impulses)), numpy_out(std::move(r.velocities)),
                                  numpy_out(std::move(r.reach)), numpy_out(std::move(r.torques)),
                                  numpy_out(std::move(r.spins)), r.settled, r.solved);
          },
          "q"_a, "v"_a, "dt"_a, "mass"_a, "force"_a, "gaps"_a, "normal_velocities"_a, "jacobian"_a, "mus"_a,
          "restitutions"_a, "torsions"_a, "spin_jacobian"_a, "guess"_a, "settings"_a, "solver"_a,
          "One step of dt [s]: (q+, v+, the contacts in the problem, impulses (k x 3) [N s], contact velocities J v+ "
          "(k x 3) [m/s], the normal velocity per unit normal impulse (k), the torsions' torque impulses [N m s] and "
          "spin velocities [rad/s] (one per torsion > 0), settled, solved); torsions: lengths [m] (k, 0: none), "
          "spin_jacobian: their rows (one per torsion > 0 x nv); guess: impulses (3k, then one per torsion > 0) "
          "[N s, N m s] for the first midpoint; settings (touch gap [m], midpoint tolerance, midpoint passes, check "
          "rtol, impulses' midpoint tolerance).");
}

}  // namespace pinstab
