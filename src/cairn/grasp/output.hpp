#pragma once
// What `cairn grasp --out DIR` writes: the planning cloud, the best grasps' gripper meshes and the
// paper's Fig. 9 (costs of all force-closure grasps vs the selected ones, normalised by median).
#include <array>
#include <filesystem>
#include <vector>

#include "cairn/core/image.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/grasp/planner.hpp"

namespace cairn::grasp {

/// The gripper's boxes as one closed triangle mesh (12 triangles each, outward), moved by T.
[[nodiscard]] io::Mesh gripper_mesh(const std::vector<ConvexPart>& parts, const Eigen::Isometry3d& T);

/// The paper's Fig. 9 data: per criterion (c_align, |c_enc|, c_dist), every force-closure grasp's
/// cost and the selected grasps' (the ranking's final keep set), each divided by the median over
/// all force-closure grasps of the planning (empty without force-closure grasps).
struct NormalizedCosts {
  std::array<std::vector<double>, 3> all, selected;
};
[[nodiscard]] NormalizedCosts normalized_costs(const GraspPlanning& planning);
inline constexpr std::array<const char*, 3> kCostNames = {"alignment c_align", "enclosing |c_enc|", "distance c_dist"};

/// Fig. 9: three panels (c_align, c_enc, c_dist), each cost divided by its median over all
/// force-closure grasps; grey dots every grasp, red dots the selected ones (the ranking's final
/// keep_enclose), a black line at 1 (the median), a grey line every 0.5. Empty panels when there
/// is no force-closure grasp.
[[nodiscard]] Image cost_figure(const GraspPlanning& planning);

/// Writes DIR/planning_cloud.ply (labels: 0 environment, 1 object, 2 ground fill), DIR/grasp_<rank>.ply
/// for the best `top` grasps (the gripper at the pre-grasp opening) and DIR/costs.png. Creates DIR.
void write_planning_outputs(const std::filesystem::path& dir, const GraspPlanning& planning,
                            const GripperConfig& gripper, int top = 5);

}  // namespace cairn::grasp
