#include "world_bias.hpp"

#include <set>
#include <string>

namespace pinstab {

bool WorldBias::applies(const pinocchio::Model& model) {
  static const std::set<std::string> constant_subspace = {
      "JointModelRX",  "JointModelRY",  "JointModelRZ",  "JointModelRevoluteUnaligned",
      "JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned",
      "JointModelPX",  "JointModelPY",  "JointModelPZ",  "JointModelPrismaticUnaligned",
      "JointModelSpherical", "JointModelTranslation", "JointModelFreeFlyer"};
  for (int i = 1; i < model.njoints; ++i) {
    if (constant_subspace.count(model.joints[i].shortname()) == 0) return false;
  }
  return true;
}

WorldBias::WorldBias(const pinocchio::Model& model)
    : velocity_(model.njoints), acceleration_(model.njoints), force_(model.njoints), bias_(model.nv) {}

const VectorXd& WorldBias::compute(const pinocchio::Model& model, const pinocchio::Data& data, const VectorXd& v) {
  velocity_[0].setZero();
  acceleration_[0] = -model.gravity;  // gravity as an acceleration of the base (Pinocchio's a_gf)
  for (int i = 1; i < model.njoints; ++i) {
    const int parent = model.parents[i], start = model.idx_vs[i], width = model.nvs[i];
    const pinocchio::Motion joint_velocity(data.J.middleCols(start, width) * v.segment(start, width));
    velocity_[i] = velocity_[parent] + joint_velocity;
    // S_i moves with body i: d/dt (S_i v_i) = v_i x (S_i v_i) at zero joint acceleration
    acceleration_[i] = acceleration_[parent] + velocity_[i].cross(joint_velocity);
    const pinocchio::Inertia inertia = data.oMi[i].act(model.inertias[i]);
    force_[i] = inertia * acceleration_[i] + velocity_[i].cross(inertia * velocity_[i]);
  }
  for (int i = model.njoints - 1; i > 0; --i) {
    const int parent = model.parents[i], start = model.idx_vs[i], width = model.nvs[i];
    bias_.segment(start, width).noalias() = data.J.middleCols(start, width).transpose() * force_[i].toVector();
    if (parent > 0) force_[parent] += force_[i];
  }
  return bias_;
}

}  // namespace pinstab
