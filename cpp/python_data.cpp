// A pin.Data (or pin.Model) from Python (a boost.python object of Pinocchio's bindings) seen as the C++ object it
// wraps, so a compiled kernel computes in a Data the Python side already has: a pin 4.1 Data of a long chain is costly to
// create (four nv^3 tensors: 135 MiB and ~65 ms at the N-four-bar N = 80).
#include <boost/python.hpp>

#include <stdexcept>

#include "geometry_features.hpp"
#include "kernels.hpp"
#include "native_kernel.hpp"

namespace pinstab {

namespace {

// The C++ object a boost.python object of Pinocchio's bindings wraps; std::invalid_argument(refusal) for another.
template <class Wrapped>
Wrapped& wrapped(PyObject* object, const char* refusal) {
  namespace converter = boost::python::converter;
  void* address = converter::get_lvalue_from_python(object, converter::registered<Wrapped>::converters);
  if (address == nullptr) throw std::invalid_argument(refusal);
  return *static_cast<Wrapped*>(address);
}

}  // namespace

pinocchio::Data& python_data(PyObject* object, const pinocchio::Model& model) {
  auto& data = wrapped<pinocchio::Data>(object, "data: not a pinocchio.Data");
  if (static_cast<int>(data.oMi.size()) != model.njoints || data.M.rows() != model.nv) {
    throw std::invalid_argument("data: a pinocchio.Data of another model");
  }
  return data;
}

const pinocchio::Model& python_model(PyObject* object) {
  return wrapped<pinocchio::Model>(object, "model: not a pinocchio.Model");
}

pinocchio::RigidConstraintModelVector& python_constraint_models(PyObject* object) {
  return wrapped<pinocchio::RigidConstraintModelVector>(object, "models: not a pinocchio.StdVec_RigidConstraintModel");
}

pinocchio::RigidConstraintDataVector& python_constraint_datas(PyObject* object) {
  return wrapped<pinocchio::RigidConstraintDataVector>(object, "datas: not a pinocchio.StdVec_RigidConstraintData");
}

const pinocchio::GeometryModel& python_geometry_model(PyObject* object) {
  return wrapped<pinocchio::GeometryModel>(object, "geometry: not a pinocchio.GeometryModel");
}

pinocchio::GeometryData& python_geometry_data(PyObject* object, const pinocchio::GeometryModel& geometry) {
  auto& data = wrapped<pinocchio::GeometryData>(object, "geometry_data: not a pinocchio.GeometryData");
  if (data.oMg.size() != geometry.ngeoms) {
    throw std::invalid_argument("geometry_data: a pinocchio.GeometryData of another geometry model");
  }
  return data;
}

}  // namespace pinstab
