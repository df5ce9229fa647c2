// pinstab._compiled: the compiled step loop (see pinstab/integration/compiled.py).
#include <memory>

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "banded_kernel.hpp"
#include "contact_terms.hpp"
#include "core_kernel.hpp"
#include "grasp_forces.hpp"
#include "inertial_term.hpp"
#include "joint_actuators.hpp"
#include "kkt_solve.hpp"
#include "native_kernel.hpp"
#include "numpy_out.hpp"
#include "series.hpp"
#include "servo_kernel.hpp"
#include "spring_damper.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace pinstab {
void bind_adaptive(nb::module_& m);  // cpp/adaptive_bindings.cpp
void bind_steps(nb::module_& m);     // cpp/step_bindings.cpp
void bind_limits(nb::module_& m);    // cpp/limit_bindings.cpp
// cpp/spring_damper_bindings.cpp: the spring-damper's terms, and its compiled form read (frames checked in the model)
void bind_spring_damper(nb::module_& m);
SpringDamperSpec spring_damper_spec(nb::dict form, const pinocchio::Model& model);
void bind_kkt_sparsity(nb::module_& m);  // cpp/kkt_sparsity_bindings.cpp (a measurement)
void bind_projection(nb::module_& m);  // cpp/projection_bindings.cpp
void bind_cones(nb::module_& m);       // cpp/cone_bindings.cpp
void bind_contact_modes(nb::module_& m);  // cpp/contact_modes_bindings.cpp
void bind_geometry_features(nb::module_& m);  // cpp/geometry_features_bindings.cpp
}  // namespace pinstab

namespace pinstab {
namespace {

Csr csr(VectorXi indptr, VectorXi indices, VectorXd data) { return Csr{std::move(indptr), std::move(indices), std::move(data)}; }

std::tuple<RowMatrix, RowMatrix, int> run(Kernel& kernel, int scheme, const VectorXd& q, const VectorXd& v,
                                          const VectorXd& tau, double dt, int steps, long start) {
  RowMatrix qs(steps, q.size()), vs(steps, v.size());
  int done;
  {
    nb::gil_scoped_release released;
    done = advance(kernel, static_cast<Scheme>(scheme), q, v, tau, dt, start, steps, qs, vs);
  }
  return {qs, vs, done};
}

// A kernel's method (stage, t, q, v, tau, dadq, dadv) -> usable bound as (q, v, tau, t, stage) -> (dadq, dadv, usable).
template <class K, class Method>
auto jacobians(Method method) {
  return [method](K& self, const VectorXd& q, const VectorXd& v, const VectorXd& tau, double t, int stage) {
    Eigen::MatrixXd dadq, dadv;
    const bool usable = (self.*method)(stage, t, q, v, tau, dadq, dadv);
    return std::make_tuple(dadq, dadv, usable);
  };
}

// f(model, data, object_frame, finger_frame) bound to a Python pin.Model and one of its pin.Data (cpp/python_data.cpp).
template <class Function>
auto on_python_data(Function function) {
  return [function](nb::handle model, nb::handle data, int object_frame, int finger_frame) {
    const pinocchio::Model& native = python_model(model.ptr());
    return function(native, python_data(data.ptr(), native), object_frame, finger_frame);
  };
}

// A target of pinstab.constraints.targets in compiled form: ("sinusoid", [offset, amplitude, omega, phase]) or
// ("piecewise", breaks, origins, coefficients, held, optionally scale [s]: 1 when absent).
Target target(nb::dict spec) {
  Target target;
  target.sinusoid = nb::cast<std::string>(spec["kind"]) == "sinusoid";
  if (target.sinusoid) {
    const VectorXd wave = nb::cast<VectorXd>(spec["wave"]);
    target.offset = wave(0), target.amplitude = wave(1), target.omega = wave(2), target.phase = wave(3);
  } else {
    target.breaks = nb::cast<VectorXd>(spec["breaks"]);
    target.origins = nb::cast<VectorXd>(spec["origins"]);
    target.coefficients = nb::cast<Eigen::MatrixXd>(spec["coefficients"]);
    target.held = nb::cast<bool>(spec["held"]);
    if (spec.contains("scale")) target.scale = nb::cast<double>(spec["scale"]);
  }
  return target;
}

// PythonPart over a Python object's methods evaluate(t, q, v) -> (G, phi, g_t, gamma0, forces) of the Python blocks
// and elements and holds(t, multipliers) -> bool (pinstab.paths.core.PythonPart), held by a weak reference: the
// object's owner keeps it (and the kernel) alive, and no reference cycle runs through C++, where Python's garbage
// collector cannot see it. Each call takes the GIL (the step loop runs without it); a part gone is not usable.
class CallbackPart : public PythonPart {
 public:
  explicit CallbackPart(nb::handle part) : part_(part) {}
  ~CallbackPart() override {
    nb::gil_scoped_acquire held;
    part_.reset();
  }
  bool evaluate(double t, const VectorXd& q, const VectorXd& v, Eigen::MatrixXd& jacobian, VectorXd& phi,
                VectorXd& time_term, VectorXd& drift, VectorXd& force) override {
    nb::gil_scoped_acquire held;
    const nb::object part = part_();
    if (part.is_none()) return false;
    const nb::tuple terms = nb::cast<nb::tuple>(part.attr("evaluate")(t, q, v));
    jacobian = nb::cast<Eigen::MatrixXd>(terms[0]);
    phi = nb::cast<VectorXd>(terms[1]);
    time_term = nb::cast<VectorXd>(terms[2]);
    drift = nb::cast<VectorXd>(terms[3]);
    force += nb::cast<VectorXd>(terms[4]);
    return jacobian.allFinite() && phi.allFinite() && time_term.allFinite() && drift.allFinite() && force.allFinite();
  }
  bool holds(double t, const VectorXd& multipliers) override {
    nb::gil_scoped_acquire held;
    const nb::object part = part_();
    return !part.is_none() && nb::cast<bool>(part.attr("holds")(t, multipliers));
  }

 private:
  nb::weakref part_;
};

// Cones from their columns (rows: normal, tangent, tangent, spin; -1: none), friction coefficients [-] and torsion
// coefficients [m]; the columns checked against the count of forces (count < 0: not checked).
std::vector<ConeSpec> cones(const Eigen::MatrixXi& columns, const VectorXd& mu, const VectorXd& torsion,
                            long count = -1) {
  if (columns.cols() != 4 || mu.size() != columns.rows() || torsion.size() != columns.rows()) {
    throw std::invalid_argument("cones: columns (k x 4: normal, tangent, tangent, spin), mu (k) and torsion (k)");
  }
  if (count >= 0 && columns.rows() && (columns.maxCoeff() >= count || columns.col(0).minCoeff() < 0)) {
    throw std::invalid_argument("cones: a column outside the forces");
  }
  std::vector<ConeSpec> cones;
  for (int k = 0; k < columns.rows(); ++k) {
    cones.push_back({columns(k, 0), columns(k, 1), columns(k, 2), columns(k, 3), mu(k), torsion(k)});
  }
  return cones;
}

// pinstab.stabilizers.mukharlyamov's inertial gains: the dict by name (stiffness, damping, rate_step, cutoff).
InertialGains inertial_gains(nb::dict gains) {
  return {nb::cast<Eigen::MatrixXd>(gains["stiffness"]), nb::cast<Eigen::MatrixXd>(gains["damping"]),
          nb::cast<double>(gains["rate_step"]), nb::cast<double>(gains["cutoff"])};
}

// pinstab.forces.joint_spring.JointSpring.compiled_form: the dict by name.
JointSpringSpec joint_spring(nb::dict form) {
  return {nb::cast<VectorXi>(form["dofs"]), nb::cast<int>(form["q_index"]), nb::cast<double>(form["stiffness"]),
          nb::cast<double>(form["reference"]), nb::cast<double>(form["damping"])};
}

// pinstab.grasp.hold.GraspHold.compiled_form: arrays by name, the cones as rows (normal, tangent1, tangent2, spin; -1:
// none).
HoldSpec hold(nb::dict form) {
  HoldSpec hold;
  hold.rows = nb::cast<VectorXi>(form["rows"]);
  hold.object_columns = nb::cast<VectorXi>(form["object_columns"]);
  hold.hand_columns = nb::cast<VectorXi>(form["hand_columns"]);
  hold.pressing = nb::cast<VectorXd>(form["pressing"]);
  hold.cones = cones(nb::cast<Eigen::MatrixXi>(form["cone_columns"]), nb::cast<VectorXd>(form["cone_mu"]),
                     nb::cast<VectorXd>(form["cone_torsion"]), hold.rows.size());
  hold.q_start = nb::cast<VectorXd>(form["q_start"]);
  hold.stiffness = nb::cast<double>(form["stiffness"]);
  hold.damping = nb::cast<double>(form["damping"]);
  hold.cap = nb::cast<double>(form["cap"]);
  hold.feasibility = nb::cast<double>(form["feasibility"]);
  hold.rank = nb::cast<double>(form["rank"]);
  hold.condition = nb::cast<double>(form["condition"]);
  return hold;
}

// The force elements' compiled forms (pinstab.forces.*.compiled_form: dicts by kind joint-spring, hold, wrench,
// spring-damper, joint-torque) for a kernel (named in the errors) of the model.
CoreForces force_forms(const std::vector<nb::dict>& forms, const pinocchio::Model& model, const std::string& kernel) {
  CoreForces forces;
  for (const nb::dict& form : forms) {
    const std::string kind = nb::cast<std::string>(form["kind"]);
    if (kind == "joint-spring") {
      forces.springs.push_back(joint_spring(form));
    } else if (kind == "hold") {
      forces.holds.push_back(hold(form));
    } else if (kind == "wrench") {
      forces.wrenches.push_back({nb::cast<int>(form["frame"]), nb::cast<Eigen::Matrix<double, 6, 1>>(form["wrench"])});
    } else if (kind == "spring-damper") {
      forces.spring_dampers.push_back(spring_damper_spec(form, model));
    } else if (kind == "joint-torque") {
      const int dof = nb::cast<int>(form["dof"]);
      if (dof < 0 || dof >= model.nv) throw std::invalid_argument(kernel + ": a joint torque's dof outside v");
      forces.torques.push_back({dof, target(nb::cast<nb::dict>(form["torque"]))});
    } else {
      throw std::invalid_argument(kernel + ": no compiled force of kind " + kind);
    }
  }
  return forces;
}

// The Model and Data of a Python pin.Model and one of its pin.Data (cpp/python_data.cpp).
std::pair<const pinocchio::Model*, pinocchio::Data*> native(nb::handle model, nb::handle data) {
  const pinocchio::Model& loaded = python_model(model.ptr());
  return {&loaded, &python_data(data.ptr(), loaded)};
}

RowBlock row_block(int kind, int frame_a, int frame_b, const Eigen::Matrix4d& world_b, const Eigen::MatrixXd& selection,
                   const VectorXd& coefficients, const VectorXi& q_indices, const VectorXi& v_indices,
                   std::optional<nb::dict> relation_target) {
  if (kind < 0 || kind > static_cast<int>(RowKind::joint_limit)) {
    throw std::invalid_argument("RowBlock: unknown kind");
  }
  RowBlock block;
  block.kind = static_cast<RowKind>(kind);
  block.frame_a = frame_a, block.frame_b = frame_b;
  block.world_b = pinocchio::SE3(world_b);
  block.selection = selection;
  block.coefficients = coefficients, block.q_indices = q_indices, block.v_indices = v_indices;
  if (relation_target) block.target = target(*relation_target);
  return block;
}

}  // namespace
}  // namespace pinstab

NB_MODULE(_compiled, m) {
  using namespace pinstab;
  m.doc() = "Compiled evaluations and explicit step loops of pinstab's native and banded paths.";
  bind_adaptive(m);
  bind_steps(m);
  bind_limits(m);
  bind_geometry_features(m);
  bind_cones(m);
  bind_spring_damper(m);
  bind_kkt_sparsity(m);
  nb::class_<Kernel>(m, "Kernel")
      .def(
          "acceleration",
          [](Kernel& self, const VectorXd& q, const VectorXd& v, const VectorXd& tau, double t, int stage) {
            VectorXd a(self.nv());
            const bool usable = self.acceleration(stage, t, q, v, tau, a);
            return std::make_tuple(a, usable);
          },
          "q"_a, "v"_a, "tau"_a, "t"_a = 0.0, "stage"_a = 0,
          "(accelerations, usable) at (t, q, v) under tau, for that stage of a step.")
      .def("jacobian", jacobians<Kernel>(&Kernel::jacobian), "q"_a, "v"_a, "tau"_a, "t"_a = 0.0, "stage"_a = 0,
          "(da/dq [1/s^2], da/dv [1/s], usable) at (t, q, v) under tau: dq in the tangent space at q (the implicit "
          "schemes' Newton matrix; by default forward differences of acceleration, cpp/jacobian.cpp).")
      .def("run", &run, "scheme"_a, "q"_a, "v"_a, "tau"_a, "dt"_a, "steps"_a, "start"_a = 0,
           "(qs, vs, done): up to `steps` steps of dt of the scheme (0 euler, 1 semi-implicit Euler, 2 Heun, 3 RK4) "
           "from grid step `start` (time start dt).");
  nb::class_<NativeKernel, Kernel>(m, "NativeKernel")
      .def(
          "__init__",
          [](NativeKernel* self, nb::handle model, const std::vector<int>& joints1,
             const std::vector<Eigen::Matrix4d>& placements1, const std::vector<int>& joints2,
             const std::vector<Eigen::Matrix4d>& placements2, double kp, double kd, double absolute_accuracy,
             double relative_accuracy, double mu, int max_iter, const std::vector<nb::dict>& forms) {
            const pinocchio::Model& loaded = python_model(model.ptr());
            std::vector<ClosureSpec> closures;
            for (size_t i = 0; i < joints1.size(); ++i) {
              closures.push_back({joints1[i], joints2[i], placements1[i], placements2[i]});
            }
            const pinocchio::ProximalSettings settings(absolute_accuracy, relative_accuracy, mu, max_iter);
            CoreForces forces = force_forms(forms, loaded, "NativeKernel");
            if (!forces.holds.empty()) throw std::invalid_argument("NativeKernel: a hold reads the core's rows");
            new (self) NativeKernel(loaded, closures, kp, kd, settings, std::move(static_cast<ForceElements&>(forces)));
          },
          "model"_a, "joints1"_a, "placements1"_a, "joints2"_a, "placements2"_a, "kp"_a, "kd"_a,
          "absolute_accuracy"_a, "relative_accuracy"_a, "mu"_a, "max_iter"_a, "forces"_a = std::vector<nb::dict>(),
          "Pinocchio's constraintDynamics on point closures with the corrector (Kp, Kd) and the proximal solve's "
          "settings (pinstab.paths.native.NativeDynamics.settings), under the applied forces plus the force elements' "
          "compiled forms (dicts by kind: joint-spring, wrench, spring-damper, joint-torque).")
      .def("derivatives", jacobians<NativeKernel>(&NativeKernel::derivatives), "q"_a, "v"_a, "tau"_a, "t"_a = 0.0, "stage"_a = 0,
          "(da/dq [1/s^2] against q (+) dq, da/dv [1/s], usable) at (t, q, v) under tau: Pinocchio's analytic "
          "derivatives plus the force elements' (NativeKernel::derivatives).")
      .def(
          "multipliers",
          [](NativeKernel& self, const VectorXd& ts, const RowMatrix& qs, const RowMatrix& vs, const VectorXd& tau,
             const Eigen::MatrixXd& rows) {
            if (ts.size() != qs.rows() || vs.rows() != qs.rows()) {
              throw std::invalid_argument("NativeKernel.multipliers: one time per sample (rows of qs, vs)");
            }
            nb::gil_scoped_release released;
            return self.multipliers(ts, qs, vs, tau, rows);
          },
          "ts"_a, "qs"_a, "vs"_a, "tau"_a, "rows"_a,
          "(multipliers rows lambda_c [N] (n, closure rows), the solves' relative residuals (n,)) at the samples "
          "(times ts [s], rows of qs, vs) under tau and the force elements; NaN where not finite or an element "
          "refuses the state.");
  m.def(
      "light_data", [](nb::handle model) { return nb::steal(new_python_data(model.ptr())); }, "model"_a,
      "A pin.Data of the model without Pinocchio's second-order derivative tensors (cpp/light_data.cpp).");
  m.def("contact_point_residual", on_python_data(contact_point_residual), "model"_a, "data"_a, "object_frame"_a,
        "finger_frame"_a, "R_o^T (p_o - p_f) (3,) from a pin.Data after a placements pass.");
  m.def("contact_point_jacobian", on_python_data(contact_point_jacobian), "model"_a, "data"_a, "object_frame"_a,
        "finger_frame"_a, "R_o^T (J_o - J_f + [p_o - p_f]x W_o) (3 x nv) from a pin.Data after a Jacobian pass.");
  m.def("contact_point_world_jacobian", on_python_data(contact_point_world_jacobian), "model"_a, "data"_a,
        "object_frame"_a, "finger_frame"_a,
        "J_o - J_f + [p_o - p_f]x W_o (3 x nv, world axes) from a pin.Data after a Jacobian pass.");
  m.def("contact_point_world_rate", on_python_data(contact_point_world_rate), "model"_a, "data"_a, "object_frame"_a,
        "finger_frame"_a,
        "v_o - v_f + (p_o - p_f) x w_o [m/s] (3,) from a pin.Data after a velocities and placements pass.");
  m.def("contact_point_drift", on_python_data(contact_point_drift), "model"_a, "data"_a, "object_frame"_a,
        "finger_frame"_a, "d2/dt2 R_o^T (p_o - p_f) at zero joint acceleration (3,) from a pin.Data after a full pass.");
  m.def(
      "closure_series",
      [](nb::handle model, nb::handle data, const std::vector<RowBlock>& blocks, const RowMatrix& qs,
         const RowMatrix& vs, const VectorXd& ts) {
        const auto [loaded, shared] = native(model, data);
        for (const RowBlock& block : blocks) {
          if (block.kind == RowKind::python) throw std::invalid_argument("closure_series: a python block (kind 6)");
        }
        if (vs.rows() != qs.rows() || ts.size() != qs.rows() || qs.cols() != loaded->nq || vs.cols() != loaded->nv) {
          throw std::invalid_argument("closure_series: qs (n x nq), vs (n x nv), ts (n)");
        }
        nb::gil_scoped_release released;
        return closure_series(*loaded, *shared, blocks, qs, vs, ts);
      },
      "model"_a, "data"_a, "blocks"_a, "qs"_a, "vs"_a, "ts"_a,
      "(max |phi| [m or rad], max |G v + g_t| [m/s or rad/s], energy [J]) per sample (rows of qs, vs at times ts [s]; "
      "NaN where not finite) of compiled row blocks (RowBlock, not python); computed in data (a pin.Data of the model, "
      "overwritten).");
  m.def(
      "servo_realizability",
      [](const Eigen::MatrixXd& decoupling, const Eigen::MatrixXd& rows, const Eigen::MatrixXd& moved,
         double rank_tolerance, std::optional<double> last_sign) {
        if (rows.rows() != decoupling.rows() || moved.cols() != decoupling.cols() || moved.rows() != rows.cols()) {
          throw std::invalid_argument("servo_realizability: D (p x k), S (p x nv), N B (nv x k)");
        }
        Realizability judged = realizability(decoupling, rows, moved, rank_tolerance, last_sign);
        return std::make_tuple(std::move(judged.unit), judged.rank, judged.sign, judged.crossed, judged.usable);
      },
      "decoupling"_a, "rows"_a, "moved"_a, "rank_tolerance"_a, "last_sign"_a = nb::none(),
      "(D_ij / (|S_i| |N b_j|) (p x k), its rank: singular values above rank_tolerance max(1, the largest), the sign of "
      "its determinant when square, else 0, crossed: square of full rank with a sign other than last_sign (the last "
      "usable evaluation's; None: none), usable: full row rank and not crossed, the only evaluation whose sign is "
      "remembered) of the decoupling matrix D = S N B (p x k), S (p x nv), N B (nv x k).");
  m.def(
      "controls_within",
      [](const VectorXd& controls, const VectorXd& lower, const VectorXd& upper) {
        if (lower.size() != controls.size() || upper.size() != controls.size()) {
          throw std::invalid_argument("controls_within: u, lower, upper (k each)");
        }
        return controls_within(controls, lower, upper);
      },
      "controls"_a, "lower"_a, "upper"_a,
      "Whether every control u_j [N m or N] lies in [lower_j, upper_j] (infinite: no bound); a NaN control lies in none.");
  m.def("least_norm", &least_norm, "decoupling"_a, "demand"_a,
        "The least-norm u with D u = demand for D (p x k) of full row rank, from a Householder QR of D^T (no cutoff).");
  nb::class_<ServoParts>(m, "ServoParts")
      .def_ro("base", &ServoParts::base, "a at u = 0 [m/s^2, rad/s^2] (nv).")
      .def_ro("base_multipliers", &ServoParts::base_multipliers, "lambda at u = 0 on the real rows [N, N m] (r).")
      .def_ro("demand", &ServoParts::demand, "rhs_S - S base (p).")
      .def_ro("moved", &ServoParts::moved, "N B (nv x k).")
      .def_ro("decoupling", &ServoParts::decoupling, "D = S N B (p x k).")
      .def(
          "finish",
          [](const ServoParts& self, const VectorXd& controls) {
            if (controls.size() != self.moved.cols()) throw std::invalid_argument("ServoParts.finish: controls (k)");
            VectorXd a, multipliers;
            self.finish(controls, a, multipliers);
            return std::make_pair(a, multipliers);
          },
          "controls"_a, "(a = base + N B u (nv), lambda on the real rows (r)) for controls u (k).");
  m.def(
      "servo_parts",
      [](const Eigen::MatrixXd& mass_matrix, const VectorXd& force, const Eigen::MatrixXd& real,
         const Eigen::MatrixXd& prescribed, const Eigen::MatrixXd& actuation, const VectorXd& real_rhs,
         const VectorXd& prescribed_rhs) {
        const Eigen::Index nv = mass_matrix.rows();
        if (mass_matrix.cols() != nv || force.size() != nv || real.cols() != nv || prescribed.cols() != nv ||
            actuation.rows() != nv || real_rhs.size() != real.rows() || prescribed_rhs.size() != prescribed.rows()) {
          throw std::invalid_argument("servo_parts: M (nv x nv), f (nv), G (r x nv), S (p x nv), B (nv x k), "
                                      "rhs_G (r), rhs_S (p)");
        }
        const Eigen::LLT<Eigen::MatrixXd> mass(mass_matrix);
        if (mass.info() != Eigen::Success) throw std::invalid_argument("servo_parts: M is not positive definite");
        ServoParts parts;
        parts.compute(mass, force, real, prescribed, actuation, real_rhs, prescribed_rhs);
        return parts;
      },
      "mass_matrix"_a, "force"_a, "real"_a, "prescribed"_a, "actuation"_a, "real_rhs"_a, "prescribed_rhs"_a,
      "The servo solve up to the controls (docs/mathematics.md section 5, cpp/servo_kernel.hpp): M a - G^T lambda - "
      "B u = f, G a = rhs_G, S a = rhs_S with the real rows G (r x nv, r = 0: none) and the prescribed rows S.");
  nb::class_<Targets>(m, "CompiledTarget")
      .def(
          "__init__",
          [](Targets* self, const std::vector<nb::dict>& components) {
            Targets compiled;
            for (const nb::dict& spec : components) compiled.components.push_back(target(spec));
            new (self) Targets(std::move(compiled));
          },
          "components"_a,
          "A target of one compiled form (pinstab.constraints.targets.TargetTrajectory.compiled) per component.")
      .def(
          "evaluate",
          [](const Targets& self, double t) {
            VectorXd value, rate, curvature;
            self.evaluate(t, value, rate, curvature);
            return nb::make_tuple(numpy_out(std::move(value)), numpy_out(std::move(rate)),
                                  numpy_out(std::move(curvature)));
          },
          "t"_a, "(x, dx/dt, d2x/dt2) of every component at t [s].");
  nb::class_<JointActuators>(m, "CompiledActuators")
      .def(
          "__init__",
          [](JointActuators* self, const std::vector<nb::dict>& controls, const Eigen::VectorXi& dofs,
             const Eigen::VectorXi& positions, const VectorXd& gear, const VectorXd& gain, const Eigen::MatrixXd& bias,
             const Eigen::MatrixXd& ctrlrange, const Eigen::MatrixXd& forcerange, int nv) {
            const Eigen::Index count = gear.size();
            if (static_cast<Eigen::Index>(controls.size()) != count || dofs.size() != count ||
                positions.size() != count || gain.size() != count || bias.rows() != 3 || bias.cols() != count ||
                ctrlrange.rows() != 2 || ctrlrange.cols() != count || forcerange.rows() != 2 ||
                forcerange.cols() != count) {
              throw std::invalid_argument("CompiledActuators: one control, dof, position, gear and gain per actuator, "
                                          "bias (3 x n), ctrlrange and forcerange (2 x n)");
            }
            if (count && (dofs.minCoeff() < 0 || dofs.maxCoeff() >= nv || positions.minCoeff() < -1)) {
              throw std::invalid_argument("CompiledActuators: a dof outside [0, nv) or a position below -1");
            }
            JointActuators made{{}, dofs, positions, gear, gain, bias, ctrlrange, forcerange, nv};
            for (const nb::dict& spec : controls) made.controls.components.push_back(target(spec));
            new (self) JointActuators(std::move(made));
          },
          "controls"_a, "dofs"_a, "positions"_a, "gear"_a, "gain"_a, "bias"_a, "ctrlrange"_a, "forcerange"_a, "nv"_a,
          "Joint actuators (cpp/joint_actuators.hpp): each one's control table (a compiled target, "
          "pinstab.forces.time_table.TimeTable.compiled), joint's velocity index and configuration index (-1: its "
          "position not read), gear [-], gain, bias (3 x n) and ranges (2 x n: low, high) of controls and forces; "
          "the model's nv.")
      .def(
          "forces",
          [](const JointActuators& self, const VectorXd& q, const VectorXd& qdot, double t) {
            if (q.size() != self.gear.size() || qdot.size() != self.gear.size()) {
              throw std::invalid_argument("CompiledActuators.forces: one position and velocity per actuator");
            }
            return numpy_out(self.forces(q, qdot, t));
          },
          "q"_a, "qdot"_a, "t"_a,
          "The actuator forces f [N or N m] at their joints' positions q [rad or m], velocities qdot and time t [s].")
      .def(
          "generalized_force",
          [](const JointActuators& self, const VectorXd& q, const VectorXd& v, double t) {
            if (v.size() != self.nv || (self.positions.size() && self.positions.maxCoeff() >= q.size())) {
              throw std::invalid_argument("CompiledActuators.generalized_force: v of size nv, q of the model's nq");
            }
            return numpy_out(self.generalized_force(q, v, t));
          },
          "q"_a, "v"_a, "t"_a,
          "Their generalized force (nv) [N or N m] at the model's configuration q and velocity v at time t [s]: each "
          "one's gear f added to its joint's coordinate, in their order.");
  m.def(
      "wrench_force",
      [](nb::handle model, nb::handle data, int frame, const Eigen::Matrix<double, 6, 1>& wrench) {
        const auto [loaded, shared] = native(model, data);
        if (frame < 0 || frame >= static_cast<int>(loaded->nframes)) {
          throw std::invalid_argument("wrench_force: no frame " + std::to_string(frame) + " in the model");
        }
        VectorXd force = VectorXd::Zero(loaded->nv);
        add_wrench(*loaded, *shared, WrenchSpec{frame, wrench}, force);
        return force;
      },
      "model"_a, "data"_a, "frame"_a, "wrench"_a,
      "J^T w [N, N m] (nv,) of a constant wrench w (force, moment) [N, N m] in world axes at a frame, J its "
      "LOCAL_WORLD_ALIGNED Jacobian from a pin.Data after a Jacobians pass.");
  nb::class_<ServoKernel, Kernel>(m, "ServoKernel")
      .def(
          "__init__",
          [](ServoKernel* self, nb::handle model, const Eigen::MatrixXd& rows, const Eigen::MatrixXd& position_rows,
             const Eigen::MatrixXd& actuation,
             const VectorXd& lower, const VectorXd& upper, const std::vector<nb::dict>& targets, double kp, double kd,
             double rank_tolerance) {
            std::vector<Target> compiled;
            for (const nb::dict& spec : targets) compiled.push_back(target(spec));
            new (self) ServoKernel(python_model(model.ptr()), rows, position_rows, actuation, lower, upper, std::move(compiled), kp, kd,
                                   rank_tolerance);
          },
          "model"_a, "rows"_a, "position_rows"_a, "actuation"_a, "lower"_a, "upper"_a, "targets"_a, "kp"_a, "kd"_a, "rank_tolerance"_a,
          "The servo path's evaluation: prescribed rows S (p x nv; position_rows p x nq), actuation B (nv x k) and bounds, targets (dicts).")
      .def_prop_ro("last_sign", &ServoKernel::last_sign);
  nb::class_<RowBlock>(m, "RowBlock")
      .def(
          "__init__",
          [](RowBlock* self, int kind, int frame_a, int frame_b, const Eigen::Matrix4d& world_b,
             const Eigen::MatrixXd& selection, const VectorXd& coefficients, const VectorXi& q_indices,
             const VectorXi& v_indices, std::optional<nb::dict> relation_target) {
            new (self) RowBlock(row_block(kind, frame_a, frame_b, world_b, selection, coefficients, q_indices,
                                          v_indices, relation_target));
          },
          "kind"_a, "frame_a"_a, "frame_b"_a, "world_b"_a, "selection"_a, "coefficients"_a = VectorXd(),
          "q_indices"_a = VectorXi(), "v_indices"_a = VectorXi(), "target"_a = nb::none(),
          "A block of standard rows (cpp/core_rows.hpp): kind 0 point, 1 weld, 2 revolute, 3 prismatic, 4 relation, "
          "5 fingertip, 7 frame target, 8 joint limit (coefficients [sign], q_indices, v_indices; its bound: .bound) (its moving side: set_frame_target); frames (frame_b < 0: world_b, a 4 x 4 placement); selection (point: rows x 3; revolute, "
          "prismatic: the 2 x 3 across the axis); a relation's coefficients, joint indices and target (a compiled "
          "target dict; none for the other kinds). A fingertip's components and limits: set_contact.")
      .def(
          "set_contact",
          [](RowBlock& self, const VectorXi& components, int model, double mu, double torsion) {
            if (model < 0 || model > static_cast<int>(ContactModel::rigid)) {
              throw std::invalid_argument("RowBlock.set_contact: unknown contact model");
            }
            self.components = components;
            self.contact_model = static_cast<ContactModel>(model);
            self.mu = mu, self.torsion = torsion;
          },
          "components"_a, "model"_a, "mu"_a, "torsion"_a,
          "A fingertip block's components of (fx, fy, fz, mx, my, mz) in C and its contact model (0 frictionless, "
          "1 point-friction, 2 soft-finger, 3 rigid), mu [-] and torsion [m].")
      .def(
          "set_target", [](RowBlock& self, nb::dict spec) { self.target = target(spec); }, "target"_a,
          "A relation's target c(t) (a compiled target dict), replacing the one it was built with.")
      .def(
          "set_frame_target",
          [](RowBlock& self, const VectorXi& components, const std::vector<nb::dict>& path, nb::dict turn,
             const Eigen::Vector3d& axis) {
            if (self.kind != RowKind::frame_target) {
              throw std::invalid_argument("RowBlock.set_frame_target: not a frame target block (kind 7)");
            }
            if ((path.size() != 0 && path.size() != 3) || components.size() > 6 ||
                (components.size() && (components.minCoeff() < 0 || components.maxCoeff() > 5))) {
              throw std::invalid_argument("RowBlock.set_frame_target: path (0 or 3 targets), components (of 0..5)");
            }
            self.components = components;
            self.path.components.clear();
            for (const nb::dict& spec : path) self.path.components.push_back(target(spec));
            self.target = target(turn);
            self.axis = axis;
          },
          "components"_a, "path"_a, "turn"_a, "axis"_a,
          "A frame target's rows (components of the weld's six: p_a - p(t) [m], log3(R_d(t)^T R_a) [rad]) and its "
          "moving side: p(t) (3 compiled target dicts [m], or none: world_b's translation), R_d(t) = exp(turn(t) "
          "axis) R_0 (turn: a compiled target dict [rad]; axis: a unit world vector; R_0: world_b's rotation).")
      .def_rw("holonomic", &RowBlock::holonomic, "False: velocity-level rows (Baumgarte's Kd / 2).")
      .def_rw("python_rows", &RowBlock::python_rows, "Kind 6 (rows Python gives): their count.")
      .def_rw("bound", &RowBlock::bound, "Kind 8 (a joint limit): its bound [rad or m].")
      .def_prop_ro("rows", &RowBlock::rows);
  m.def(
      "contact_margins",
      [](int model, double mu, double torsion, const Eigen::Matrix<double, 6, 1>& wrench) {
        return contact_margins(static_cast<ContactModel>(model), mu, torsion, wrench);
      },
      "model"_a, "mu"_a, "torsion"_a, "wrench"_a,
      "(normal, friction, torsion) margins [N, N, N m] of a wrench in C (inf: no such limit).");
  m.def(
      "contact_holds",
      [](int model, double mu, double torsion, const Eigen::Matrix<double, 6, 1>& wrench, double slack) {
        return contact_holds(static_cast<ContactModel>(model), mu, torsion, wrench, slack);
      },
      "model"_a, "mu"_a, "torsion"_a, "wrench"_a, "slack"_a,
      "Whether every margin is above -slack (1 + the largest |component|).");
  m.def(
      "closest_solution",
      [](const Eigen::MatrixXd& matrix, const VectorXd& rhs, const VectorXd& target, double rank, double condition) {
        VectorXd x;
        const bool finite = closest_solution(matrix, rhs, target, rank, condition, x);
        return std::make_pair(x, finite);
      },
      "matrix"_a, "rhs"_a, "target"_a, "rank"_a, "condition"_a,
      "(target + A^+ (rhs - A target), finite): Cholesky of A A^T where its condition allows, else the SVD.");
  m.def(
      "cones_hold",
      [](const Eigen::MatrixXi& columns, const VectorXd& mu, const VectorXd& torsion, double cap, double feasibility,
         const VectorXd& forces) {
        return cones_hold(cones(columns, mu, torsion, forces.size()), cap, feasibility, forces);
      },
      "columns"_a, "mu"_a, "torsion"_a, "cap"_a, "feasibility"_a, "forces"_a,
      "Every force finite and every contact (rows of columns: normal, tangent, tangent, spin; -1: none) inside its "
      "cone (mu) and torsion limit (torsion [m]) with its normal force within the cap (inf: none), beyond a slack of "
      "feasibility (1 + the largest |force|).");
  m.def(
      "hold_torques",
      [](const Eigen::MatrixXd& rows, const VectorXi& hand_columns, const VectorXd& gravity, const VectorXd& forces,
         const VectorXd& deviation, const VectorXd& v, double stiffness, double damping) {
        const long nv = rows.cols();
        if (forces.size() != rows.rows() || gravity.size() != nv || deviation.size() != nv || v.size() != nv ||
            (hand_columns.size() && (hand_columns.minCoeff() < 0 || hand_columns.maxCoeff() >= nv))) {
          throw std::invalid_argument("hold_torques: rows (s x nv), hand columns in nv, gravity, deviation, v (nv), "
                                      "forces (s)");
        }
        VectorXd torques = VectorXd::Zero(nv);
        const VectorXi all = VectorXi::LinSpaced(rows.rows(), 0, static_cast<int>(rows.rows()) - 1);
        add_hold_balance(rows, all, hand_columns, gravity, forces, deviation, v, stiffness, damping, torques);
        return torques;
      },
      "rows"_a, "hand_columns"_a, "gravity"_a, "forces"_a, "deviation"_a, "v"_a, "stiffness"_a, "damping"_a,
      "The hand's torques [N m] (nv,; 0 off the hand columns) that make the held forces (s,) on the contact rows A "
      "(s x nv) an equilibrium: g - A^T forces - stiffness deviation - damping v on the hand columns.");
  m.def(
      "primal_residual",
      [](const Eigen::MatrixXd& jacobian, const VectorXd& a, const VectorXd& rhs, const VectorXd& force,
         const VectorXd& mass_diagonal, const Mask& unilateral) {
        if (jacobian.rows() != rhs.size() || jacobian.cols() != a.size() || force.size() != a.size() ||
            mass_diagonal.size() != a.size() || (unilateral.size() && unilateral.size() != rhs.size())) {
          throw std::invalid_argument("primal_residual: G (s x nv), a (nv), rhs (s), f (nv), diag M (nv), mask (s)");
        }
        return primal_residual(jacobian, a, rhs, force, mass_diagonal, unilateral);
      },
      "jacobian"_a, "a"_a, "rhs"_a, "force"_a, "mass_diagonal"_a, "unilateral"_a,
      "|G a - rhs| / (|rhs| + |G|_F (|a| + |f| / min diag M)) [-], a unilateral row (mask) counted only when violated.");
  m.def(
      "delassus_pseudo_inverse",
      [](const Eigen::MatrixXd& delassus, double cutoff) {
        if (delassus.rows() != delassus.cols()) throw std::invalid_argument("delassus_pseudo_inverse: D must be square");
        DelassusPseudoInverse inverse;
        inverse.compute(delassus, cutoff);
        return inverse.apply(Eigen::MatrixXd(Eigen::MatrixXd::Identity(delassus.rows(), delassus.cols())));
      },
      "delassus"_a, "cutoff"_a,
      "D^+ of a Delassus matrix D = G M^-1 G^T (symmetric positive semi-definite), its eigenvalues at most cutoff times "
      "the largest left out (the core solve's pseudo-inverse; NaN where D is not finite).");
  m.def(
      "inertial_matrices",
      [](nb::dict gains, const Eigen::MatrixXd& mass, const Eigen::MatrixXd& jacobian, const Eigen::MatrixXd& mass_ahead,
         const Eigen::MatrixXd& jacobian_ahead) {
        const InertialGains given = inertial_gains(gains);
        if (jacobian.rows() != given.damping.rows() || jacobian_ahead.rows() != jacobian.rows() ||
            given.stiffness.rows() != jacobian.rows() || mass.rows() != jacobian.cols()) {
          throw std::invalid_argument("inertial_matrices: H and B need one row per constraint row, M one per column");
        }
        return inertial_matrices(given, mass, jacobian, mass_ahead, jacobian_ahead);
      },
      "gains"_a, "mass"_a, "jacobian"_a, "mass_ahead"_a, "jacobian_ahead"_a,
      "(S = D H [1/s^2], K = D B - dD/dt D^+ [1/s]) of Mukharlyamov's inertial variant (the core kernel's), D = G M^-1 "
      "G^T from M and G at q and at q + rate_step v (dD/dt by their difference); gains: dict of stiffness H, damping B, "
      "rate_step [s], cutoff (of D^+, relative).");
  m.def(
      "stabilization_term",
      [](double stiffness, const VectorXd& velocity_gains, const VectorXd& phi, const VectorXd& rate) {
        if (velocity_gains.size() != phi.size() || rate.size() != phi.size()) {
          throw std::invalid_argument("stabilization_term: velocity_gains, phi and rate need one entry per row");
        }
        return stabilization_term(stiffness, velocity_gains.array(), phi, rate);
      },
      "stiffness"_a, "velocity_gains"_a, "phi"_a, "rate"_a,
      "The stabilization term per row, -K rate - S phi (the core kernel's): phi [m or rad] (zero on nonholonomic "
      "rows), rate = G v + g_t [m/s or rad/s], the stiffness S [1/s^2], the velocity gains K per row [1/s].");
  m.def(
      "baumgarte_velocity_gains",
      [](double kd, const Mask& holonomic) -> VectorXd { return baumgarte_velocity_gains(kd, holonomic).matrix(); },
      "kd"_a, "holonomic"_a, "Baumgarte's velocity gain per row [1/s]: Kd on holonomic rows, Kd / 2 on nonholonomic ones.");
  m.def(
      "direct_solve",
      [](const Eigen::MatrixXd& mass, const VectorXd& force, const Eigen::MatrixXd& jacobian, const VectorXd& rhs,
         double direct_pivot) -> std::optional<std::pair<VectorXd, VectorXd>> {
        if (mass.rows() != mass.cols() || force.size() != mass.rows() || jacobian.cols() != mass.rows() ||
            rhs.size() != jacobian.rows()) {
          throw std::invalid_argument("direct_solve: M (nv x nv), f (nv), G (s x nv), rhs (s)");
        }
        CoreSolve settings;
        settings.direct_pivot = direct_pivot;
        KktSolve kkt;
        if (kkt.solve(mass, force, jacobian, rhs, settings, false) != KktOutcome::direct) return std::nullopt;
        return std::make_pair(kkt.acceleration(), kkt.multipliers());
      },
      "mass"_a, "force"_a, "jacobian"_a, "rhs"_a, "direct_pivot"_a,
      "(a, lambda) of M a = f + G^T lambda, G a = rhs by Cholesky factors of M and of D = G M^-1 G^T (the core "
      "kernel's direct solve); None when M is not positive definite, the result not finite, or D's smallest pivot "
      "squared is below direct_pivot times its largest diagonal entry.");
  m.def(
      "joint_spring_force",
      [](nb::dict form, const VectorXd& q, const VectorXd& v) {
        const JointSpringSpec spring = joint_spring(form);
        if (spring.dofs.size() == 0 || spring.dofs.maxCoeff() >= v.size() || spring.dofs.minCoeff() < 0 ||
            spring.q_index >= q.size()) {
          throw std::invalid_argument("joint_spring_force: the spring's indices are outside q, v");
        }
        VectorXd force = VectorXd::Zero(v.size());
        add_joint_springs({spring}, q, v, force);
        return force;
      },
      "form"_a, "q"_a, "v"_a,
      "A joint spring's generalized force [N, N m] (nv,) at (q, v) from its compiled form (JointSpring.compiled_form).");
  m.def(
      "native_residual",
      [](nb::handle model, nb::handle data, nb::handle models, nb::handle datas, const Eigen::MatrixXd& rows, double kp,
         double kd, const VectorXd& v, const VectorXd& a) {
        const auto [loaded, shared] = native(model, data);
        pinocchio::RigidConstraintModelVector& closures = python_constraint_models(models.ptr());
        pinocchio::RigidConstraintDataVector& contacts = python_constraint_datas(datas.ptr());
        if (closures.size() != contacts.size() || rows.cols() != 3 * static_cast<long>(contacts.size()) ||
            v.size() != loaded->nv || a.size() != loaded->nv) {
          throw std::invalid_argument("native_residual: one data per closure, rows (s x 3 closures), v and a (nv)");
        }
        return native_residual(*loaded, *shared, closures, contacts, rows, kp, kd, v, a);
      },
      "model"_a, "data"_a, "models"_a, "datas"_a, "rows"_a, "kp"_a, "kd"_a, "v"_a, "a"_a,
      "primal_residual without the free force's scale, |G a - rhs| / (|rhs| + |G|_F |a|) [-], of the last "
      "constraintDynamics solve in data, datas of point closures (rhs = -gamma0 - Kp phi - Kd G v on the rows); NaN "
      "where not finite.");
  m.def(
      "tilted_gravity",
      [](const Eigen::Vector3d& axis, double rate, double start, const Eigen::Vector3d& gravity0, double t,
         double stop) { return GravityTilt{axis, gravity0, rate, start, stop}.gravity(t); },
      "axis"_a, "rate"_a, "start"_a, "gravity0"_a, "t"_a, "stop"_a = std::numeric_limits<double>::infinity(),
      "R(axis, -angle) g0 [m/s^2], angle = start + rate t [rad] until it reaches stop [rad] (inf: never).");
  m.def(
      "block_residual",
      [](nb::handle model, nb::handle data, const RowBlock& block, const VectorXd& q, double t) {
        const auto [loaded, shared] = native(model, data);
        VectorXd phi(block.rows());
        block_residual(*loaded, *shared, block, q, t, phi);
        return phi;
      },
      "model"_a, "data"_a, "block"_a, "q"_a, "t"_a, "phi [m or rad] of a block from a pin.Data after a placements pass.");
  m.def(
      "block_jacobian",
      [](nb::handle model, nb::handle data, const RowBlock& block, double t) {
        const auto [loaded, shared] = native(model, data);
        Eigen::MatrixXd jacobian(block.rows(), loaded->nv);
        VectorXd time_term(block.rows());
        block_jacobian(*loaded, *shared, block, t, jacobian, time_term);
        return std::make_pair(jacobian, time_term);
      },
      "model"_a, "data"_a, "block"_a, "t"_a,
      "(G (rows x nv), g_t) of a block from a pin.Data after a Jacobians and placements pass.");
  m.def(
      "block_rate",
      [](nb::handle model, nb::handle data, const RowBlock& block, const VectorXd& v, double t) {
        const auto [loaded, shared] = native(model, data);
        if (v.size() != loaded->nv) throw std::invalid_argument("block_rate: v (nv)");
        VectorXd rate(block.rows());
        block_rate(*loaded, *shared, block, v, t, rate);
        return rate;
      },
      "model"_a, "data"_a, "block"_a, "v"_a, "t"_a,
      "g = G v + g_t [m/s or rad/s] of a block without forming G, from a pin.Data after a velocities pass "
      "(forwardKinematics(q, v)) and placements.");
  m.def(
      "block_drift",
      [](nb::handle model, nb::handle data, const RowBlock& block, double t) {
        const auto [loaded, shared] = native(model, data);
        VectorXd drift(block.rows());
        block_drift(*loaded, *shared, block, t, drift);
        return drift;
      },
      "model"_a, "data"_a, "block"_a, "t"_a, "gamma0 of a block from a pin.Data after a full pass and placements.");
  m.def("rotation_drift", &rotation_drift, "rotation_a"_a, "rotation_b"_a, "omega_a"_a, "omega_b"_a,
        "relative_angular_drift"_a,
        "gamma0 of the rows log3(R_b^T R_a) [rad/s^2] from the rotations, the angular velocities [rad/s] and "
        "alpha_a - alpha_b at zero joint acceleration [rad/s^2], world axes.");
  nb::class_<CoreKernel, Kernel>(m, "CoreKernel")
      .def(
          "__init__",
          [](CoreKernel* self, nb::handle model, std::vector<RowBlock> blocks, const std::vector<nb::dict>& forms,
             double stiffness, const VectorXd& velocity_gains, bool held, nb::dict settings,
             std::optional<nb::dict> tilt, nb::object python, std::optional<nb::dict> inertial) {
            CoreForces forces = force_forms(forms, python_model(model.ptr()), "CoreKernel");
            CoreSolve solve;
            solve.direct_pivot = nb::cast<double>(settings["direct_pivot"]);
            solve.cutoff = nb::cast<double>(settings["cutoff"]);
            solve.accepted = nb::cast<double>(settings["accepted"]);
            solve.margin_slack = nb::cast<double>(settings["margin_slack"]);
            std::optional<GravityTilt> turning;
            if (tilt) {
              turning = GravityTilt{nb::cast<Eigen::Vector3d>((*tilt)["axis"]),
                                    nb::cast<Eigen::Vector3d>((*tilt)["gravity0"]), nb::cast<double>((*tilt)["rate"]),
                                    nb::cast<double>((*tilt)["start"]), nb::cast<double>((*tilt)["stop"])};
            }
            std::shared_ptr<PythonPart> part;
            if (!python.is_none()) part = std::make_shared<CallbackPart>(python);
            CoreTerm term{stiffness, velocity_gains.array(), held, std::nullopt};
            if (inertial) term.inertial = inertial_gains(*inertial);
            new (self) CoreKernel(python_model(model.ptr()), std::move(blocks), std::move(forces), std::move(term),
                                  solve, turning, std::move(part));
          },
          "model"_a, "blocks"_a, "forces"_a, "stiffness"_a, "velocity_gains"_a, "held"_a, "settings"_a,
          "tilt"_a = nb::none(),
          "python"_a = nb::none(), "inertial"_a = nb::none(),
          "The core evaluation: row blocks, the force elements' compiled forms (dicts by kind: joint-spring, hold, "
          "wrench, spring-damper, joint-torque), the stabilization term -K (G v + g_t) - S phi (S [1/s^2], K per row [1/s], held: computed at a "
          "step's stage 0 and held over its other stages), the solve's settings (dict: direct_pivot, cutoff, "
          "accepted, margin_slack) and a gravity tilt (dict: axis, gravity0, rate, start, stop) or None, and the Python part or None: an object (held "
          "weakly: its owner keeps it alive) with evaluate(t, q, v) -> (G, phi, g_t, gamma0, forces) of the blocks of "
          "kind 6 and the elements without a compiled form, and holds(t, multipliers) -> bool; inertial: Mukharlyamov's "
          "inertial term instead of S and K (dict: stiffness H (s x s), damping B (s x s), rate_step [s], cutoff), "
          "or None.")
      .def("multipliers", &CoreKernel::multipliers, "The last evaluation's multipliers [N, N m] (the rows' order).")
      .def("held_term", &CoreKernel::held_term,
           "The term held over the step (computed at its last stage-0 evaluation) [m/s^2 or rad/s^2], or None: a term "
           "not held, none computed yet, or the last stage-0 evaluation stopped before its rows.")
      .def_prop_ro("worst_residual", &CoreKernel::worst_residual,
                   "The largest relative |G a - rhs| of the evaluations used (solvers.base.primal_residual).")
      .def_prop_ro("status_counts", &CoreKernel::status_counts,
                   "Evaluations by how they were solved: cholesky, pseudo-inverse, pseudo-inverse, not accepted (not used).");
  nb::class_<BandedKernel, Kernel>(m, "BandedKernel")
      .def(
          "__init__",
          [](BandedKernel* self, nb::handle model, nb::dict arrays, int band, double kp, double kd,
             double pivot_tolerance, nb::handle data) {
            auto vi = [&](const char* key) { return nb::cast<VectorXi>(arrays[key]); };
            auto vd = [&](const char* key) { return nb::cast<VectorXd>(arrays[key]); };
            auto md = [&](const char* key) { return nb::cast<Eigen::MatrixXd>(arrays[key]); };
            BandedPattern pattern;
            pattern.carried = vi("carried");
            pattern.joints = vi("joints");
            pattern.local = md("local");
            pattern.fixed_points = md("fixed_points");
            pattern.row_map = csr(vi("row_map_indptr"), vi("row_map_indices"), vd("row_map_data"));
            pattern.g_columns = vi("g_columns");
            pattern.g_linear = md("g_linear");
            pattern.g_map = csr(vi("g_map_indptr"), vi("g_map_indices"), vd("g_map_data"));
            pattern.m_rows = vi("m_rows");
            pattern.m_cols = vi("m_cols");
            pattern.m_off = vi("m_off");
            pattern.scatter = vi("scatter");
            pattern.acceleration_slots = vi("acceleration_slots");
            pattern.row_slots = vi("row_slots");
            pattern.band = band;
            GramSpectrum::Pattern gram;
            gram.entry_rows = vi("gram_entry_rows");
            gram.entry_cols = vi("g_columns");
            gram.pair_first = vi("gram_pair_first");
            gram.pair_second = vi("gram_pair_second");
            gram.pair_slot = vi("gram_pair_slot");
            gram.rows = static_cast<int>(pattern.row_slots.size());
            gram.band = vi("gram_band")(0);  // one entry
            const pinocchio::Model& loaded = python_model(model.ptr());
            pinocchio::Data* shared = data.is_none() ? nullptr : &python_data(data.ptr(), loaded);
            new (self) BandedKernel(loaded, std::move(pattern), std::move(gram), kp, kd, pivot_tolerance, shared);
          },
          "model"_a, "arrays"_a, "band"_a, "kp"_a, "kd"_a, "pivot_tolerance"_a, "data"_a = nb::none(),
          nb::keep_alive<1, 8>(),  // a shared pin.Data lives as long as the kernel
          "The banded path's evaluation; data: a pin.Data of the model to compute in (shared), or None for its own.")
      .def_prop_ro("singular", &BandedKernel::singular)
      .def_prop_ro("refinements", &BandedKernel::refinements)
      .def_prop_ro("pivot_ratio", &BandedKernel::pivot_ratio)
      .def("multipliers", &BandedKernel::multipliers)
      .def("violation", &BandedKernel::violation, "q"_a, "v"_a,
           "(max |phi| [m], max |G v| [m/s]) over the closures' rows at (q, v).")
      .def("relative_singular_value", &BandedKernel::relative_singular_value, "q"_a, "rank"_a,
           "sigma_r / sigma_1 of the closures' Jacobian at q.")
      .def("values", &BandedKernel::values, "q"_a, "(phi [m], G's entries) of the closures at q.")
      .def(
          "project",
          [](BandedKernel& self, const VectorXd& q, const VectorXd& rows) {
            VectorXd x;
            const bool usable = self.project(q, rows, x);
            return std::make_tuple(x, usable);
          },
          "q"_a, "rows"_a, "(M^-1 G^T (G M^-1 G^T)^-1 rows, usable) at q.");
  bind_projection(m);  // after CoreKernel, which its classes take
  bind_contact_modes(m);  // after CoreKernel, whose methods it adds
}
