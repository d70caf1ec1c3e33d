// The robot library: the angular gripper's one geometry (Sec. 5), the excavator model built from
// it, and the grasp-plan contract with its JSON form.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "cairn/core/error.hpp"
#include "cairn/robot/excavator_model.hpp"
#include "cairn/robot/grasp_plan.hpp"
#include "cairn/robot/gripper.hpp"

namespace cairn {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

/// Inner tip edge of a jaw (its corner at the tip on the inner face, z = 0), in G.
Vector3d inner_tip(const GripperConfig& g, JawSide side, double angle) {
  return T_gripper_jaw(g, side, angle) * Vector3d(g.jaw_length, 0.0, 0.0);
}

TEST(Gripper, OpeningIsTheTipDistanceOfTheCoupledJaws) {
  const GripperConfig g;
  EXPECT_NO_THROW(validate(g));
  for (double opening : {0.2, 0.8, 1.3, 1.9}) {
    const double angle = jaw_angle_for(g, opening);
    EXPECT_NEAR(opening_at(g, angle), opening, 1e-12);
    EXPECT_NEAR((inner_tip(g, JawSide::Right, angle) - inner_tip(g, JawSide::Left, angle)).norm(), opening, 1e-12);
  }
  // Parallel jaws at the pivot spacing; fully closed at the gap; fully open at 35 deg.
  EXPECT_NEAR(jaw_angle_for(g, g.hinge_spacing), 0.0, 1e-12);
  EXPECT_NEAR(opening_at(g, min_jaw_angle(g)), g.closed_gap, 1e-12);
  EXPECT_NEAR(max_opening(g), g.hinge_spacing + 2.0 * g.jaw_length * std::sin(35.0 * std::numbers::pi / 180.0), 1e-12);
  EXPECT_NEAR(jaw_angle_for(g, 5.0), max_jaw_angle(g), 1e-12);  // clamped
  EXPECT_NEAR(jaw_angle_for(g, 0.0), min_jaw_angle(g), 1e-12);
}

TEST(Gripper, PartsAreThePalmAndTheJawsAtTheirPivots) {
  const GripperConfig g;
  const std::vector<ConvexPart> parts = gripper_parts(g, 1.4);
  ASSERT_EQ(parts.size(), 3u);
  EXPECT_EQ(parts[0].name, "palm");
  EXPECT_EQ(parts[1].name, "jaw_left");
  EXPECT_EQ(parts[2].name, "jaw_right");
  const double angle = jaw_angle_for(g, 1.4);
  for (int j = 1; j <= 2; ++j) {
    const JawSide side = j == 1 ? JawSide::Left : JawSide::Right;
    const ConvexPart& jaw = parts[static_cast<std::size_t>(j)];
    // The pivot and the inner tip edge lie on the jaw's boundary; the jaw is outside the
    // closing region, on its own side.
    const Vector3d pivot(0.0, (j == 1 ? -0.5 : 0.5) * g.hinge_spacing, 0.0);
    EXPECT_TRUE(jaw.contains(pivot, 1e-9));
    EXPECT_FALSE(jaw.contains(pivot, -1e-9));
    EXPECT_TRUE(jaw.contains(inner_tip(g, side, angle), 1e-9));
    EXPECT_LT((j == 1 ? 1.0 : -1.0) * jaw.center.y(), 0.0);
    for (const Vector3d& v : jaw.vertices) EXPECT_FALSE(in_closing_region(g, 1.4, v - 1e-6 * (jaw.center - v)));
  }
  // The palm lies behind the origin; the jaws do not reach into it.
  for (const Vector3d& v : parts[0].vertices) EXPECT_LE(v.x(), 1e-12);
  // Closing region: between the jaws' inner faces (at depth x: hinge_spacing / 2 + x tan(angle)
  // off the centre line), in front of the palm, within the jaws' height.
  const double edge = 0.5 * g.hinge_spacing + 0.5 * std::tan(angle);  // at x = 0.5
  EXPECT_TRUE(in_closing_region(g, 1.4, {0.5, 0.0, 0.0}));
  EXPECT_TRUE(in_closing_region(g, 1.4, {0.5, edge - 0.01, 0.2}));
  EXPECT_FALSE(in_closing_region(g, 1.4, {0.5, edge + 0.01, 0.0}));   // beyond the right jaw's face
  EXPECT_FALSE(in_closing_region(g, 1.4, {0.5, -edge - 0.01, 0.0}));  // beyond the left one's
  EXPECT_FALSE(in_closing_region(g, 1.4, {-0.1, 0.0, 0.0}));  // behind the palm's face
  EXPECT_FALSE(in_closing_region(g, 1.4, {0.5, 0.0, 0.5 * g.jaw_height + 0.01}));  // above the jaws
  EXPECT_FALSE(in_closing_region(g, 1.4, {g.jaw_length + 0.01, 0.0, 0.0}));      // past the tips
}

TEST(Gripper, ValidateNamesTheField) {
  GripperConfig g;
  g.hinge_spacing = 2.0;  // wider than the palm
  try {
    validate(g);
    FAIL() << "accepted hinges outside the palm";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("hinge_spacing"), std::string::npos) << e.what();
  }
  g = GripperConfig{};
  g.max_jaw_angle_deg = 95.0;
  EXPECT_THROW(validate(g), ConfigError);
  g = GripperConfig{};
  g.jaw_length = 0.2;  // the tips could not close across the pivots
  EXPECT_THROW(validate(g), ConfigError);
}

TEST(ExcavatorModel, JawLinksAreTheGripperParts) {
  // One definition: the excavator's jaw shapes, posed by forward kinematics at a jaw angle, are
  // the boxes gripper_parts gives for that opening (in the gripper link's frame).
  const GripperConfig g;
  const RobotModel robot = make_excavator_model(g);
  JointState q;
  set_jaw_opening(q, g, 1.2);
  const std::vector<Isometry3d> T = robot.forward_kinematics(q);
  const int gripper = robot.link_index("gripper");
  ASSERT_GE(gripper, 0);
  const std::vector<ConvexPart> parts = gripper_parts(g, 1.2);
  for (const ConvexPart& part : parts) {
    const int link = robot.link_index(part.name == "palm" ? "gripper" : part.name);
    ASSERT_GE(link, 0) << part.name;
    const Link& l = robot.links[static_cast<std::size_t>(link)];
    ASSERT_EQ(l.shapes.size(), 1u);
    const Isometry3d T_gripper_shape = T[static_cast<std::size_t>(gripper)].inverse() *
                                       T[static_cast<std::size_t>(link)] * l.shapes[0].T_link_shape;
    EXPECT_TRUE(T_gripper_shape.translation().isApprox(part.center, 1e-12)) << part.name;
    EXPECT_TRUE(T_gripper_shape.linear().isApprox(part.axes, 1e-12)) << part.name;
    EXPECT_TRUE(l.shapes[0].size.isApprox(2.0 * part.half_extents, 1e-12)) << part.name;
  }
  EXPECT_DOUBLE_EQ(q.get(joints::kJawLeft), q.get(joints::kJawRight));
}

TEST(GraspPlan, JsonRoundTripsAndRejectsBadInput) {
  GraspPlan plan;
  plan.T_world_gripper.linear() = Eigen::AngleAxisd(0.3, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  plan.T_world_gripper.translation() = Vector3d(1.5, -2.0, 0.8);
  plan.T_world_place.translation() = Vector3d(3.0, 1.0, 0.9);
  plan.opening = 1.3;
  plan.swing_pivot = Eigen::Vector2d(1.0, -2.0);
  plan.place_com_xy = Eigen::Vector2d(3.25, 0.5);
  plan.target_stone = 2;
  const GraspPlan back = grasp_plan_from_json(to_json(plan), "test");
  ASSERT_TRUE(back.place_com_xy.has_value());
  EXPECT_EQ(*back.place_com_xy, *plan.place_com_xy);
  EXPECT_FALSE(grasp_plan_from_json(nlohmann::json{{"T_world_gripper", to_json(plan)["T_world_gripper"]}}, "x")
                   .place_com_xy.has_value());
  EXPECT_TRUE(back.T_world_gripper.isApprox(plan.T_world_gripper, 1e-8));
  EXPECT_TRUE(back.T_world_place.isApprox(plan.T_world_place, 1e-8));
  EXPECT_DOUBLE_EQ(back.opening, plan.opening);
  ASSERT_TRUE(back.swing_pivot.has_value());
  EXPECT_EQ(back.target_stone, 2);
  const nlohmann::json quat = {{"T_world_gripper", {{"position", {1, 2, 3}}, {"quaternion_wxyz", {0, 1, 0, 0}}}}};
  EXPECT_TRUE(grasp_plan_from_json(quat, "q").T_world_gripper.translation().isApprox(Vector3d(1, 2, 3)));
  EXPECT_THROW(grasp_plan_from_json(nlohmann::json{{"opening", 1.0}}, "x"), InputError);
  EXPECT_THROW(grasp_plan_from_json(nlohmann::json{{"T_world_gripper", 1}, {"bogus", 2}}, "x"), InputError);
  // The contract's checks: within the gripper's range, rigid poses.
  const GripperConfig g;
  EXPECT_NO_THROW(validate(plan, g));
  GraspPlan wide = plan;
  wide.opening = max_opening(g) + 0.01;
  EXPECT_THROW(validate(wide, g), InputError);
  GraspPlan shut = plan;
  shut.opening = g.closed_gap;  // nothing to close: the jaws start fully closed
  EXPECT_THROW(validate(shut, g), InputError);
  GraspPlan nan_place = plan;
  nan_place.place_com_xy->x() = std::nan("");
  EXPECT_THROW(validate(nan_place, g), InputError);
  GraspPlan skew = plan;
  skew.T_world_place.linear()(0, 0) += 0.1;
  EXPECT_THROW(validate(skew, g), InputError);
}

}  // namespace
}  // namespace cairn
