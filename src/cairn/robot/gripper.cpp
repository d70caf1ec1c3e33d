#include "cairn/robot/gripper.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "cairn/core/error.hpp"
#include "cairn/core/units.hpp"

namespace cairn {
namespace {


ConvexPart box_part(std::string name, const Eigen::Vector3d& center, const Eigen::Vector3d& half,
                    const Eigen::Isometry3d& T = Eigen::Isometry3d::Identity()) {
  ConvexPart part{.name = std::move(name), .vertices = {}, .center = T * center, .half_extents = half,
                  .axes = T.linear()};
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d sign((i & 1) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 4) ? 1.0 : -1.0);
    part.vertices.push_back(T * (center + sign.cwiseProduct(half)));
  }
  return part;
}

double side_sign(JawSide side) { return side == JawSide::Left ? -1.0 : 1.0; }

}  // namespace

void validate(const GripperConfig& c) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto require = [](bool ok, const std::string& message) {
    if (!ok) throw ConfigError("GripperConfig: " + message);
  };
  require(positive(c.palm_depth) && positive(c.palm_width) && positive(c.palm_height),
          "palm_depth, palm_width and palm_height must be > 0");
  require(positive(c.jaw_length) && positive(c.jaw_thickness) && positive(c.jaw_height),
          "jaw_length, jaw_thickness and jaw_height must be > 0");
  require(positive(c.hinge_spacing) && c.hinge_spacing <= c.palm_width,
          "hinge_spacing must be > 0 and at most palm_width (the pivots sit on the palm)");
  require(std::isfinite(c.closed_gap) && c.closed_gap >= 0.0 && c.closed_gap < c.hinge_spacing,
          "closed_gap must lie in [0, hinge_spacing)");
  require(0.5 * c.hinge_spacing - 0.5 * c.closed_gap <= c.jaw_length,
          "jaw_length must reach across half the hinge spacing (the tips must be able to close)");
  require(std::isfinite(c.max_jaw_angle_deg) && c.max_jaw_angle_deg > 0.0 && c.max_jaw_angle_deg < 90.0,
          "max_jaw_angle_deg must lie in (0, 90)");
  require(positive(c.closing_force), "closing_force must be > 0");
  require(std::isfinite(c.tcp_depth) && c.tcp_depth >= 0.0, "tcp_depth must be >= 0");
}

double opening_at(const GripperConfig& c, double angle) {
  return c.hinge_spacing + 2.0 * c.jaw_length * std::sin(angle);
}

double min_jaw_angle(const GripperConfig& c) {
  return std::asin(std::clamp((0.5 * c.closed_gap - 0.5 * c.hinge_spacing) / c.jaw_length, -1.0, 1.0));
}

double max_jaw_angle(const GripperConfig& c) { return c.max_jaw_angle_deg * kDeg; }

double max_opening(const GripperConfig& c) { return opening_at(c, max_jaw_angle(c)); }

double closing_torque(const GripperConfig& c) { return c.closing_force * c.jaw_length; }

double jaw_angle_for(const GripperConfig& c, double opening) {
  const double s = std::clamp((opening - c.hinge_spacing) / (2.0 * c.jaw_length), -1.0, 1.0);
  return std::clamp(std::asin(s), min_jaw_angle(c), max_jaw_angle(c));
}

Eigen::Vector3d jaw_axis(JawSide side) { return side_sign(side) * Eigen::Vector3d::UnitZ(); }

Eigen::Isometry3d T_gripper_jaw(const GripperConfig& c, JawSide side, double angle) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.0, side_sign(side) * 0.5 * c.hinge_spacing, 0.0);
  T.linear() = Eigen::AngleAxisd(angle, jaw_axis(side)).toRotationMatrix();
  return T;
}

bool ConvexPart::contains(const Eigen::Vector3d& p, double padding) const {
  const Eigen::Vector3d local = axes.transpose() * (p - center);
  return (local.cwiseAbs() - half_extents).maxCoeff() <= padding;
}

ConvexPart palm_part(const GripperConfig& c) {
  return box_part("palm", {-0.5 * c.palm_depth, 0.0, 0.0},
                  {0.5 * c.palm_depth, 0.5 * c.palm_width, 0.5 * c.palm_height});
}

ConvexPart jaw_part(const GripperConfig& c, JawSide side) {
  const double s = side_sign(side);
  return box_part(side == JawSide::Left ? "jaw_left" : "jaw_right",
                  {0.5 * c.jaw_length, s * 0.5 * c.jaw_thickness, 0.0},
                  {0.5 * c.jaw_length, 0.5 * c.jaw_thickness, 0.5 * c.jaw_height});
}

std::vector<ConvexPart> gripper_parts(const GripperConfig& c, double opening) {
  const double angle = jaw_angle_for(c, opening);
  std::vector<ConvexPart> parts{palm_part(c)};
  for (const JawSide side : {JawSide::Left, JawSide::Right}) {
    const ConvexPart local = jaw_part(c, side);
    parts.push_back(box_part(local.name, local.center, local.half_extents, T_gripper_jaw(c, side, angle)));
  }
  return parts;
}

JawLines jaw_lines(const GripperConfig& c, double angle) {
  return {.half_spacing = 0.5 * c.hinge_spacing, .length = c.jaw_length, .height = c.jaw_height,
          .tan_angle = std::tan(angle), .reach = c.jaw_length * std::cos(angle)};
}

bool in_closing_region(const GripperConfig& c, double opening, const Eigen::Vector3d& p) {
  return jaw_lines(c, jaw_angle_for(c, opening)).encloses(p);
}

}  // namespace cairn
