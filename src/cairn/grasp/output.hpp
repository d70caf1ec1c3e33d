#pragma once
// What `cairn grasp --out DIR` writes: the planning cloud, the best grasps' gripper meshes and the
// paper's Fig. 9 (costs of all force-closure grasps vs the selected ones, normalised by median).
#include <filesystem>

#include "cairn/core/image.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/grasp/planner.hpp"

namespace cairn::grasp {

/// The gripper's boxes as one closed triangle mesh (12 triangles each, outward), moved by T.
[[nodiscard]] io::Mesh gripper_mesh(const std::vector<ConvexPart>& parts, const Eigen::Isometry3d& T);

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
