// A pin.Data (or pin.Model) from Python (a boost.python object of Pinocchio's bindings) seen as the C++ object it
// wraps, so a compiled kernel computes in a Data the Python side already has: a pin 4.1 Data of a long chain is costly to
// create (four nv^3 tensors: 135 MiB and ~65 ms at the N-four-bar N = 80).
#include <boost/python.hpp>

#include <stdexcept>

#include "kernels.hpp"

namespace pinstab {

pinocchio::Data& python_data(PyObject* object, const pinocchio::Model& model) {
  namespace converter = boost::python::converter;
  void* address = converter::get_lvalue_from_python(object, converter::registered<pinocchio::Data>::converters);
  if (address == nullptr) throw std::invalid_argument("data: not a pinocchio.Data");
  auto& data = *static_cast<pinocchio::Data*>(address);
  if (static_cast<int>(data.oMi.size()) != model.njoints || data.M.rows() != model.nv) {
    throw std::invalid_argument("data: a pinocchio.Data of another model");
  }
  return data;
}

const pinocchio::Model& python_model(PyObject* object) {
  namespace converter = boost::python::converter;
  void* address = converter::get_lvalue_from_python(object, converter::registered<pinocchio::Model>::converters);
  if (address == nullptr) throw std::invalid_argument("model: not a pinocchio.Model");
  return *static_cast<const pinocchio::Model*>(address);
}

}  // namespace pinstab
