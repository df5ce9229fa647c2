#include "spring_damper.hpp"

#include <pinocchio/algorithm/frames.hpp>

namespace pinstab {

SpringLine spring_line(const pinocchio::Model& model, pinocchio::Data& data, const SpringDamperSpec& spring) {
  Eigen::Matrix<double, 6, Eigen::Dynamic> frame = Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, model.nv);
  pinocchio::getFrameJacobian(model, data, spring.frame_a, pinocchio::LOCAL_WORLD_ALIGNED, frame);
  SpringLine line{data.oMf[spring.frame_a].translation(), frame.topRows<3>()};
  if (spring.frame_b < 0) {
    line.difference -= spring.point_b;
    return line;
  }
  frame.setZero();
  pinocchio::getFrameJacobian(model, data, spring.frame_b, pinocchio::LOCAL_WORLD_ALIGNED, frame);
  line.difference -= data.oMf[spring.frame_b].translation();
  line.jacobian -= frame.topRows<3>();
  return line;
}

std::optional<SpringDamperTerms> spring_damper_terms(const SpringDamperSpec& spring, const SpringLine& line,
                                                      const VectorXd& v) {
  SpringDamperTerms terms;
  terms.length = line.difference.norm();
  if (terms.length < kCoincidentLength) {  // no direction: only the zero-rest-length spring's -k (p_a - p_b) is had
    if (spring.stiffness * spring.rest_length != 0.0 || spring.damping != 0.0) return std::nullopt;
    terms.force = line.jacobian.transpose() * (-spring.stiffness * line.difference);
    return terms;
  }
  const Eigen::Vector3d direction = line.difference / terms.length;
  terms.rate = direction.dot(line.jacobian * v);
  const double magnitude = -(spring.stiffness * (terms.length - spring.rest_length) + spring.damping * terms.rate);
  terms.force = line.jacobian.transpose() * (magnitude * direction);
  return terms;
}

bool add_spring_damper(const pinocchio::Model& model, pinocchio::Data& data, const SpringDamperSpec& spring,
                       const VectorXd& v, Eigen::Ref<VectorXd> force) {
  const std::optional<SpringDamperTerms> terms = spring_damper_terms(spring, spring_line(model, data, spring), v);
  if (!terms) return false;
  force += terms->force;
  return true;
}

}  // namespace pinstab
