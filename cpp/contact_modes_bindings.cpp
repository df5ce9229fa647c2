// pinstab._compiled's plane contacts in given modes (cpp/contact_modes.hpp) on the core kernel: CoreKernel's
// set_contacts, set_contact_modes and contact_solution (pinstab.solvers.core_modes).
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/tuple.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "core_kernel.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {

namespace {

ContactModes& contacts_of(CoreKernel& kernel) {
  ContactModes* contacts = kernel.contacts();
  if (contacts == nullptr) throw std::invalid_argument("CoreKernel: no contacts (set_contacts first)");
  return *contacts;
}

void set_contacts(CoreKernel& kernel, const VectorXi& frames, const VectorXi& plane_frames, const RowMatrix& bases,
                  const RowMatrix& origins, const VectorXd& radii, const VectorXd& mus, nb::dict settings) {
  const Eigen::Index k = frames.size();
  if (plane_frames.size() != k || bases.rows() != 3 * k || bases.cols() != 3 || origins.rows() != k ||
      origins.cols() != 3 || radii.size() != k || mus.size() != k) {
    throw std::invalid_argument("CoreKernel.set_contacts: per contact a frame, a plane frame, a basis (3 rows), an "
                                "origin (3), a radius and mu");
  }
  const int frames_in_model = static_cast<int>(kernel.model().nframes);
  std::vector<PlaneContact> contacts(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    if (frames(i) < 0 || frames(i) >= frames_in_model || plane_frames(i) < -1 || plane_frames(i) >= frames_in_model) {
      throw std::invalid_argument("CoreKernel.set_contacts: a frame outside the model's (plane frame -1: the world)");
    }
    contacts[i] = {frames(i), plane_frames(i), radii(i), bases.middleRows<3>(3 * i), origins.row(i).transpose()};
  }
  ContactSettings limits{nb::cast<double>(settings["held_rank"]), nb::cast<double>(settings["rank_tolerance"]),
                         nb::cast<double>(settings["slip_floor"]), nb::cast<double>(settings["grazing_speed"])};
  kernel.set_contacts(ContactModes(std::move(contacts), mus, limits));
}

void set_contact_modes(CoreKernel& kernel, const VectorXi& modes, const RowMatrix& directions,
                       const RowMatrix& references, const VectorXi& continued) {
  std::vector<ContactMode> chosen(modes.size());
  for (Eigen::Index i = 0; i < modes.size(); ++i) {
    if (modes(i) < 0 || modes(i) > 2) throw std::invalid_argument("CoreKernel.set_contact_modes: modes are 0, 1, 2");
    chosen[i] = static_cast<ContactMode>(modes(i));
  }
  contacts_of(kernel).set_modes(chosen, directions, references, (continued.array() != 0).eval());
}

nb::tuple contact_solution(CoreKernel& kernel) {
  const ContactModes& contacts = contacts_of(kernel);
  const PlaneContactRows& rows = contacts.rows();
  return nb::make_tuple(contacts.forces(), contacts.free(), contacts.mobility(), rows.gaps, rows.positions, rows.local,
                        rows.velocities, rows.jacobian, rows.drift, contacts.residual());
}

}  // namespace

void bind_contact_modes(nb::module_& m) {
  const nb::handle kernel = nb::type<CoreKernel>();
  nb::cpp_function_def(
      &set_contacts, nb::scope(kernel), nb::name("set_contacts"), nb::is_method(), "frames"_a, "plane_frames"_a,
      "bases"_a, "origins"_a, "radii"_a, "mus"_a, "settings"_a,
      "Solve plane contacts in modes in place of the KKT solve (cpp/contact_modes.hpp), the rows held: each "
      "contact's frame, plane frame (-1: the world), basis rows (n, t1, t2) (3k x 3) and plane origin (k x 3) [m] in "
      "the plane's axes, sphere radius [m] and mu; "
      "settings: dict of held_rank, rank_tolerance, slip_floor [m/s], grazing_speed [m/s].");
  nb::cpp_function_def(
      &set_contact_modes, nb::scope(kernel), nb::name("set_contact_modes"), nb::is_method(), "modes"_a,
      "directions"_a, "references"_a, "continued"_a,
      "The contacts' modes (0 sticking, 1 sliding, 2 separated), fallback slip directions (k x 2, (t1, t2)), the "
      "directions continued slips keep (k x 2) and whether each is continued (k, 0 or 1).");
  nb::cpp_function_def(
      &contact_solution, nb::scope(kernel), nb::name("contact_solution"), nb::is_method(),
      "The last evaluation's contact forces (k x 3) [N, basis], accelerations without contact forces, their "
      "response (nv x 3k), gaps (k) [m], points (k x 3) [m, world] and in the planes' axes, velocities (k x 3) "
      "[m/s, basis], Jacobian (3k x nv), drift (3k) [m/s^2] and the force system's relative residual.");
}

}  // namespace pinstab
