#include <pinocchio/serialization/model.hpp>

#include "kernels.hpp"

namespace pinstab {

pinocchio::Model model_from_string(const std::string& text) {
  pinocchio::Model model;
  model.loadFromString(text);
  return model;
}

}  // namespace pinstab
