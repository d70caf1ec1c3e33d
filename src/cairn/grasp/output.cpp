#include "cairn/grasp/output.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "cairn/core/stats.hpp"

namespace cairn::grasp {
namespace {

// Faces of a box_part (vertex bits: 1 = +x, 2 = +y, 4 = +z), counter-clockwise from outside.
constexpr std::array<std::array<std::uint32_t, 4>, 6> kQuads{{{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                                              {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}}};
constexpr int kPanel = 220, kHeight = 320, kGap = 10;  // [px]
constexpr double kMaxRatio = 3.0;                       // costs drawn up to 3x their median

void dot(Image& img, int cx, int cy, Rgb c) {
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) {
      const int x = cx + dx, y = cy + dy;
      if (x >= 0 && y >= 0 && x < img.width && y < img.height && dx * dx + dy * dy <= 5) img.at(x, y) = c;
    }
}

void hline(Image& img, int x0, int x1, int y, Rgb c) {
  if (y < 0 || y >= img.height) return;
  for (int x = std::max(0, x0); x < std::min(img.width, x1); ++x) img.at(x, y) = c;
}

int row_of(double ratio) { return kHeight - 10 - int(std::round(std::clamp(ratio, 0.0, kMaxRatio) / kMaxRatio * (kHeight - 20))); }

int jitter(std::size_t i) { return int((i * 2654435761u) % std::uint32_t(kPanel / 2 - 20)); }

/// One panel: all grasps in the left half, the selected in the right half (jittered by index),
/// both already divided by the median over all.
void panel(Image& img, int x0, const std::vector<double>& all, const std::vector<double>& selected) {
  for (double r = 0.5; r <= kMaxRatio; r += 0.5) hline(img, x0, x0 + kPanel, row_of(r), {220, 220, 220});
  hline(img, x0, x0 + kPanel, row_of(1.0), {0, 0, 0});
  for (std::size_t i = 0; i < all.size(); ++i) dot(img, x0 + 10 + jitter(i), row_of(all[i]), {150, 150, 150});
  for (std::size_t i = 0; i < selected.size(); ++i)
    dot(img, x0 + kPanel / 2 + 10 + jitter(i), row_of(selected[i]), {210, 40, 40});
}

std::array<std::vector<double>, 3> split(const std::vector<Costs>& costs) {
  std::array<std::vector<double>, 3> out;
  for (const Costs& c : costs) {
    out[0].push_back(c.align);
    out[1].push_back(std::abs(c.enclose));
    out[2].push_back(c.dist);
  }
  return out;
}

}  // namespace

io::Mesh gripper_mesh(const std::vector<ConvexPart>& parts, const Eigen::Isometry3d& T) {
  io::Mesh mesh;
  for (const ConvexPart& p : parts) {
    const auto base = std::uint32_t(mesh.vertices.size());
    for (const Eigen::Vector3d& v : p.vertices) mesh.vertices.points.push_back((T * v).cast<float>());
    for (const auto& q : kQuads) {
      mesh.triangles.push_back({base + q[0], base + q[1], base + q[2]});
      mesh.triangles.push_back({base + q[0], base + q[2], base + q[3]});
    }
  }
  return mesh;
}

NormalizedCosts normalized_costs(const GraspPlanning& p) {
  NormalizedCosts n{.all = split(p.force_closure_costs), .selected = split(p.selected_costs)};
  for (std::size_t k = 0; k < 3; ++k) {
    const double m = n.all[k].empty() ? 1.0 : std::max(median(n.all[k]), 1e-9);
    for (double& v : n.all[k]) v /= m;
    for (double& v : n.selected[k]) v /= m;
  }
  return n;
}

Image cost_figure(const GraspPlanning& p) {
  Image img(3 * kPanel + 2 * kGap, kHeight);
  const NormalizedCosts n = normalized_costs(p);
  for (std::size_t k = 0; k < 3; ++k) panel(img, int(k) * (kPanel + kGap), n.all[k], n.selected[k]);
  return img;
}

void write_planning_outputs(const std::filesystem::path& dir, const GraspPlanning& p, const GripperConfig& g, int top) {
  std::filesystem::create_directories(dir);
  io::write_ply(dir / "planning_cloud.ply", p.cloud.cloud);
  for (const Grasp& gr : p.grasps) {
    if (gr.rank > top) break;
    io::write_ply_mesh(dir / ("grasp_" + std::to_string(gr.rank) + ".ply"), gripper_mesh(gripper_parts(g, gr.opening), gr.T_map_gripper));
  }
  write_png(dir / "costs.png", cost_figure(p));
}

}  // namespace cairn::grasp
