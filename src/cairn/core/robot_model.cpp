#include "cairn/core/robot_model.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"

namespace cairn {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kAxisTolerance = 1e-6;

/// Slab test of the ray against the axis-aligned box [-h, h].
double box_entry(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& h) {
  double t0 = 0.0, t1 = kInf;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-15) {
      if (std::abs(o[i]) > h[i]) return kInf;
      continue;
    }
    double a = (-h[i] - o[i]) / d[i], b = (h[i] - o[i]) / d[i];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return kInf;
  }
  return t0;
}

/// Ray against the finite cylinder x^2 + y^2 <= r^2, |z| <= h (side and caps).
double cylinder_entry(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double r, double h) {
  double t0 = 0.0, t1 = kInf;
  // Caps: slab in z.
  if (std::abs(d.z()) < 1e-15) {
    if (std::abs(o.z()) > h) return kInf;
  } else {
    double a = (-h - o.z()) / d.z(), b = (h - o.z()) / d.z();
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  // Side: quadratic in the xy plane.
  const double A = d.x() * d.x() + d.y() * d.y();
  const double B = 2.0 * (o.x() * d.x() + o.y() * d.y());
  const double C = o.x() * o.x() + o.y() * o.y() - r * r;
  if (A < 1e-30) {
    if (C > 0) return kInf;
  } else {
    const double disc = B * B - 4 * A * C;
    if (disc < 0) return kInf;
    const double sq = std::sqrt(disc);
    t0 = std::max(t0, (-B - sq) / (2 * A));
    t1 = std::min(t1, (-B + sq) / (2 * A));
  }
  return t0 <= t1 ? t0 : kInf;
}

const char* kind_name(Shape::Kind k) { return k == Shape::Kind::Box ? "box" : "cylinder"; }
const char* joint_type_name(Link::Joint j) {
  switch (j) {
    case Link::Joint::Revolute: return "revolute";
    case Link::Joint::Prismatic: return "prismatic";
    default: return "fixed";
  }
}
Eigen::Vector3d vec3(const nlohmann::json& j, const char* what) {
  if (!j.is_array() || j.size() != 3) throw InputError(std::string("robot model: ") + what + " must be [x, y, z]");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}
nlohmann::json vec_json(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }
}  // namespace

bool Shape::contains(const Eigen::Vector3d& p, double padding) const {
  if (kind == Kind::Box) return ((p.cwiseAbs() - 0.5 * size).array() <= padding).all();
  const double r = 0.5 * size.x() + padding;
  return std::abs(p.z()) <= 0.5 * size.z() + padding && p.head<2>().squaredNorm() <= r * r;
}

double Shape::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
  if (kind == Kind::Box) return box_entry(o, d, 0.5 * size);
  return cylinder_entry(o, d, 0.5 * size.x(), 0.5 * size.z());
}

double Shape::bounding_radius() const { return 0.5 * size.norm(); }

JointState interpolate_joints(const std::vector<JointState>& states, double t) {
  if (states.empty()) throw InputError("interpolate_joints: no joint states");
  if (t <= states.front().time) return states.front();
  if (t >= states.back().time) return states.back();
  const auto it = std::upper_bound(states.begin(), states.end(), t,
                                   [](double v, const JointState& s) { return v < s.time; });
  const JointState& b = *it;
  const JointState& a = *(it - 1);
  const double s = (b.time > a.time) ? (t - a.time) / (b.time - a.time) : 0.0;
  JointState q = a;
  q.time = t;
  for (std::size_t i = 0; i < q.names.size(); ++i)
    q.positions[i] = (1 - s) * a.positions[i] + s * b.get(a.names[i], a.positions[i]);
  return q;
}

Shape bounding_box_shape(std::string name, const std::vector<Eigen::Vector3d>& points) {
  if (points.empty()) throw InputError("bounding_box_shape: no points for '" + name + "'");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) {
    if (!p.allFinite()) throw InputError("bounding_box_shape: a non-finite point in '" + name + "'");
    mean += p;
  }
  mean /= double(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
  Eigen::Matrix3d axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors();
  if (axes.determinant() < 0) axes.col(0) = -axes.col(0);  // a rotation
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const auto& p : points) {
    const Eigen::Vector3d q = axes.transpose() * (p - mean);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  Shape s{.kind = Shape::Kind::Box, .name = std::move(name), .T_link_shape = Eigen::Isometry3d::Identity(), .size = hi - lo};
  s.T_link_shape.linear() = axes;
  s.T_link_shape.translation() = mean + axes * (0.5 * (lo + hi));
  return s;
}

double JointState::get(const std::string& joint, double fallback) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == joint) return positions[i];
  return fallback;
}

void JointState::set(const std::string& joint, double value) {
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == joint) {
      positions[i] = value;
      return;
    }
  }
  names.push_back(joint);
  positions.push_back(value);
}

int RobotModel::link_index(const std::string& link) const {
  for (std::size_t i = 0; i < links.size(); ++i)
    if (links[i].name == link) return static_cast<int>(i);
  return -1;
}

std::vector<std::string> RobotModel::joint_names() const {
  std::vector<std::string> names;
  for (const auto& l : links)
    if (l.joint != Link::Joint::Fixed) names.push_back(l.joint_name);
  return names;
}

std::vector<Eigen::Isometry3d> RobotModel::forward_kinematics(const JointState& q) const {
  std::vector<Eigen::Isometry3d> T(links.size(), Eigen::Isometry3d::Identity());
  for (std::size_t i = 0; i < links.size(); ++i) {
    const Link& l = links[i];
    Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
    if (l.joint == Link::Joint::Revolute) {
      motion.linear() = Eigen::AngleAxisd(q.get(l.joint_name), l.axis).toRotationMatrix();
    } else if (l.joint == Link::Joint::Prismatic) {
      motion.translation() = q.get(l.joint_name) * l.axis;
    }
    const Eigen::Isometry3d parent = l.parent < 0 ? Eigen::Isometry3d::Identity() : T[static_cast<std::size_t>(l.parent)];
    T[i] = parent * l.T_parent_joint * motion;
  }
  return T;
}

void RobotModel::validate() const {
  for (std::size_t i = 0; i < links.size(); ++i) {
    const Link& l = links[i];
    if (l.parent >= static_cast<int>(i) || (i > 0 && l.parent < 0) || (i == 0 && l.parent != -1)) {
      throw InputError("robot model: link '" + l.name + "' has an invalid parent (parents must come first)");
    }
    if (l.joint != Link::Joint::Fixed && std::abs(l.axis.norm() - 1.0) > kAxisTolerance) {
      throw InputError("robot model: joint axis of link '" + l.name + "' is not a unit vector");
    }
    for (const auto& s : l.shapes) {
      if (!(s.size.array() > 0).all() || !s.size.allFinite()) {
        throw InputError("robot model: shape '" + s.name + "' of link '" + l.name + "' has a non-positive size");
      }
    }
  }
}

nlohmann::json to_json(const RobotModel& robot) {
  nlohmann::json links = nlohmann::json::array();
  for (const auto& l : robot.links) {
    nlohmann::json shapes = nlohmann::json::array();
    for (const auto& s : l.shapes) {
      shapes.push_back({{"name", s.name}, {"kind", kind_name(s.kind)},
                        {"T_link_shape", matrix_to_json(s.T_link_shape.matrix())}, {"size", vec_json(s.size)}});
    }
    links.push_back({{"name", l.name},
                     {"parent", l.parent < 0 ? nlohmann::json(nullptr) : nlohmann::json(robot.links[static_cast<std::size_t>(l.parent)].name)},
                     {"joint", joint_type_name(l.joint)},
                     {"joint_name", l.joint_name},
                     {"T_parent_joint", matrix_to_json(l.T_parent_joint.matrix())},
                     {"axis", vec_json(l.axis)},
                     {"shapes", shapes}});
  }
  return {{"name", robot.name}, {"links", links}};
}

RobotModel robot_from_json(const nlohmann::json& j) {
  try {
    RobotModel robot;
    robot.name = j.value("name", "");
    for (const auto& jl : j.at("links")) {
      Link l;
      l.name = jl.at("name").get<std::string>();
      if (!jl.at("parent").is_null()) {
        l.parent = robot.link_index(jl.at("parent").get<std::string>());
        if (l.parent < 0) throw InputError("robot model: parent of link '" + l.name + "' not defined before it");
      }
      const std::string type = jl.at("joint").get<std::string>();
      if (type == "revolute") l.joint = Link::Joint::Revolute;
      else if (type == "prismatic") l.joint = Link::Joint::Prismatic;
      else if (type == "fixed") l.joint = Link::Joint::Fixed;
      else throw InputError("robot model: unknown joint type '" + type + "'");
      l.joint_name = jl.value("joint_name", "");
      l.T_parent_joint = Eigen::Isometry3d(matrix_from_json(jl.at("T_parent_joint")));
      l.axis = vec3(jl.at("axis"), "axis");
      for (const auto& js : jl.at("shapes")) {
        Shape s;
        s.name = js.at("name").get<std::string>();
        const std::string kind = js.at("kind").get<std::string>();
        if (kind == "box") s.kind = Shape::Kind::Box;
        else if (kind == "cylinder") s.kind = Shape::Kind::Cylinder;
        else throw InputError("robot model: unknown shape kind '" + kind + "'");
        s.T_link_shape = Eigen::Isometry3d(matrix_from_json(js.at("T_link_shape")));
        s.size = vec3(js.at("size"), "size");
        l.shapes.push_back(std::move(s));
      }
      robot.links.push_back(std::move(l));
    }
    robot.validate();
    return robot;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("robot model: ") + e.what());
  }
}

RobotModel read_robot_model(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot open robot model '" + path + "'");
  try {
    return robot_from_json(nlohmann::json::parse(in));
  } catch (const nlohmann::json::exception& e) {
    throw InputError("robot model '" + path + "': " + e.what());
  } catch (const InputError& e) {
    throw InputError("'" + path + "': " + e.what());
  }
}

}  // namespace cairn
