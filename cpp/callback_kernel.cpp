#include "callback_kernel.hpp"

#include <nanobind/eigen/dense.h>

#include <stdexcept>
#include <string>

namespace pinstab {

CallbackKernel::CallbackKernel(nb::handle acceleration, int nv, const pinocchio::Model* group, nb::handle refusals,
                               nb::handle jacobian)
    : acceleration_(acceleration), refusals_(refusals), nv_(nv), group_(group) {
  if (jacobian.is_valid() && !jacobian.is_none()) jacobian_ = nb::cast<Kernel*>(jacobian);
}

bool CallbackKernel::jacobian(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd& tau,
                              Eigen::MatrixXd& dadq, Eigen::MatrixXd& dadv) {
  if (jacobian_ == nullptr) return Kernel::jacobian(stage, t, q, v, tau, dadq, dadv);
  // the one-step bindings pass no applied forces (the Python evaluation applies the scene's): the kernel's are none
  return jacobian_->jacobian(stage, t, q, v, tau.size() == nv_ ? tau : VectorXd::Zero(nv_).eval(), dadq, dadv);
}

void CallbackKernel::share(const VectorXd& q, nb::handle q_array, const VectorXd& v, nb::handle v_array) {
  q0_ = &q, v0_ = &v, q0_array_ = q_array, v0_array_ = v_array;
}

namespace {

nb::object array(const VectorXd& x, const VectorXd* start, nb::handle start_array) {
  if (&x == start) return nb::borrow(start_array);
  return nb::cast(VectorXd(x));
}

}  // namespace

bool CallbackKernel::acceleration(int stage, double t, const VectorXd& q, const VectorXd& v, const VectorXd&,
                                  VectorXd& a) {
  nb::gil_scoped_acquire held;
  refused_ = false;
  try {
    const nb::object result = acceleration_(array(q, q0_, q0_array_), array(v, v0_, v0_array_), t, stage);
    a = nb::cast<VectorXd>(result);
  } catch (nb::python_error& error) {
    if (refusals_.is_valid() && !refusals_.is_none() && error.matches(refusals_)) {
      refused_ = true;
      refusal_ = nb::borrow(error.value());
    } else {
      pending_ = nb::borrow(error.value());
    }
    return false;
  }
  if (a.size() != nv_) {
    throw std::invalid_argument("the acceleration of a step has " + std::to_string(a.size()) + " entries, not nv = " +
                                std::to_string(nv_));
  }
  return true;
}

nb::object CallbackKernel::raised(bool refusal_too) const {
  if (pending_.is_valid()) return pending_;
  if (refusal_too && refusal_.is_valid()) return refusal_;
  return nb::none();
}

RunKernel::RunKernel(nb::handle kernel, int nv) {
  if (nb::isinstance<Kernel>(kernel)) {
    compiled = nb::cast<Kernel*>(kernel);
    return;
  }
  if (!nb::isinstance<nb::tuple>(kernel) || nb::len(kernel) < 3 || nb::len(kernel) > 4) {
    throw std::invalid_argument(
        "a run's kernel is a Kernel or (acceleration, pin.Model or None, refusals[, the Jacobians' Kernel or None])");
  }
  auto part = [&](Py_ssize_t i) { return nb::handle(PyTuple_GET_ITEM(kernel.ptr(), i)); };  // borrowed
  callback.emplace(part(0), nv, python_group(part(1)), part(2), nb::len(kernel) == 4 ? part(3) : nb::handle());
}

void reraise(nb::handle exception) {
  PyErr_Restore(nb::handle(exception.type()).inc_ref().ptr(), exception.inc_ref().ptr(),
                PyException_GetTraceback(exception.ptr()));
  throw nb::python_error();
}

const pinocchio::Model* python_group(nb::handle model) {
  return model.is_none() ? nullptr : &python_model(model.ptr());
}

}  // namespace pinstab
