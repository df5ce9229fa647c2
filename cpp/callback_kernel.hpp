// A Kernel whose evaluation is a Python callable (pinstab.system.ConstrainedSystem.acceleration: the general path's
// KKT solve, a Python stabilizer's term, a compiled path's fallbacks), so that the compiled loops (advance,
// adaptive_advance) and the one-step bindings take the steps of every path with one loop.
#pragma once

#include <nanobind/nanobind.h>

#include <optional>

#include "adaptive.hpp"

namespace pinstab {

namespace nb = nanobind;

// acceleration(q, v, t, stage) -> (nv,) array, called with the GIL held (acquired when the caller released it). An
// exception it raises makes the evaluation not to be used: one matching `refusals` (a class or tuple of classes;
// none: no class) is a refusal of the trial's state (refused(): the error-controlled loop shortens the step, as
// AdaptiveLoop.attempt did with a contact leaving its cone), kept in refusal; any other is kept in pending, for the
// caller to raise once the loop has handed back its steps. The handles are borrowed: made for one call, the kernel
// keeps no Python object alive (no reference cycle runs through C++).
class CallbackKernel : public Kernel, public Refusing {
 public:
  // jacobian: a compiled Kernel whose Jacobians Newton's iteration takes (the run's compiled kernel, so that a step
  // the Python evaluation takes iterates as the compiled loop's would), or None: differences of this evaluation.
  CallbackKernel(nb::handle acceleration, int nv, const pinocchio::Model* group, nb::handle refusals = nb::handle(),
                 nb::handle jacobian = nb::handle());
  bool acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                    VectorXd& a) override;
  bool jacobian(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau, Eigen::MatrixXd& dadq,
                Eigen::MatrixXd& dadv) override;
  int nv() const override { return nv_; }
  const pinocchio::Model* group() const override { return group_; }
  bool refused() const override { return refused_; }
  // The caller's own arrays for the state (q, v): passed as they are instead of copies when a stage is at it.
  void share(const VectorXd& q, nb::handle q_array, const VectorXd& v, nb::handle v_array);
  // The exception to raise now (the pending one; with `refusal_too`, else a refusal): None when there is none.
  nb::object raised(bool refusal_too) const;

 private:
  nb::handle acceleration_, refusals_;
  int nv_;
  const pinocchio::Model* group_;
  Kernel* jacobian_ = nullptr;
  const VectorXd *q0_ = nullptr, *v0_ = nullptr;
  nb::handle q0_array_, v0_array_;
  bool refused_ = false;
  nb::object pending_, refusal_;
};

// The kernel of a compiled run: a compiled Kernel, or (acceleration, pin.Model or None, refusals[, Kernel or None: the
// Jacobians' kernel]) of the Python evaluation (a CallbackKernel, made here for one call).
struct RunKernel {
  Kernel* compiled = nullptr;
  std::optional<CallbackKernel> callback;

  RunKernel(nb::handle kernel, int nv);
  Kernel& operator*() { return compiled != nullptr ? *compiled : *callback; }
  // The exception to raise (the callback's, its refusal too), or None.
  nb::object raised() const { return callback ? callback->raised(true) : nb::none(); }
};

// Raise `exception` (a Python exception object) in C++ (nb::python_error), its traceback kept.
[[noreturn]] void reraise(nb::handle exception);

// The model's group of a Python pin.Model or None (every joint of one coordinate: q (+) dq = q + dq).
const pinocchio::Model* python_group(nb::handle model);

}  // namespace pinstab
