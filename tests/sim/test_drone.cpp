// Drone pre-map (Sec. 4.1): the photogrammetry-like cloud lies on the true surfaces through the
// true similarity, occluded terrain is missing, every point is seen by two cameras, the SfM and
// VINS camera positions relate by the true similarity, and everything is deterministic.
#include "cairn/sim/drone.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include "cairn/core/error.hpp"
#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/plane.hpp"
#include "cairn/sim/world.hpp"
#include "support/test_data.hpp"

namespace cairn::sim {
namespace {

using Eigen::Vector3d;

constexpr std::uint64_t kSiteSeed = 7;
constexpr std::uint64_t kDroneSeed = 42;
constexpr double kTolerance = 0.04;  // [m] point-to-surface distance counted as "on the surface"

SiteConfig small_site_config() {
  SiteConfig c;
  c.terrain.size_x = c.terrain.size_y = 7.0;
  c.stones.count = 3;
  c.stones.placement_radius = 1.6;
  c.stones.min_volume = 0.3;
  c.stones.max_volume = 0.5;
  c.stones.min_spacing = 0.3;
  return c;
}

/// A smaller camera and region than the defaults, so the test runs in about a second.
DroneConfig small_drone_config() {
  DroneConfig c;
  c.altitude = 9.0;
  c.extent_x = c.extent_y = 4.0;
  c.orbit_images = 12;
  c.orbit_radius = 5.0;
  c.camera = {.width = 400, .height = 256, .fx = 330.0, .fy = 330.0, .cx = 200.0, .cy = 128.0};
  return c;
}

/// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Vector3d closest_on_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double mesh_distance(const io::Mesh& mesh, const Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : mesh.triangles) {
    const Vector3d q = closest_on_triangle(p, mesh.vertices.world(t[0]), mesh.vertices.world(t[1]),
                                           mesh.vertices.world(t[2]));
    best = std::min(best, (q - p).norm());
  }
  return best;
}

/// Distance of p to each surface: [0] terrain (vertical), [1 + k] stone k (inf when far away).
std::vector<double> surface_distances(const Site& site, const Vector3d& p) {
  std::vector<double> d{std::abs(p.z() - site.terrain.height(p.x(), p.y()))};
  for (const auto& s : site.stones) {
    const double box = s.bounds.exteriorDistance(p);
    d.push_back(box > 0.2 ? std::numeric_limits<double>::infinity() : mesh_distance(s.mesh, p));
  }
  return d;
}

std::vector<Vector3d> world_points(const DroneSurvey& s, const Similarity& T_world_sfm) {
  std::vector<Vector3d> w(s.cloud.size());
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = T_world_sfm * s.cloud.world(i);
  return w;
}

struct Fixture {
  Site site;
  RayScene scene;
  DroneConfig config;
  DroneSurvey survey;
};

const Fixture& fixture() {
  static const std::unique_ptr<Fixture> f = [] {
    auto x = std::make_unique<Fixture>();
    x->site = generate_site(small_site_config(), kSiteSeed);
    x->scene = make_world_scene(x->site, 0.02);
    x->config = small_drone_config();
    x->survey = simulate_drone(x->site, x->scene, x->config, kDroneSeed);
    return x;
  }();
  return *f;
}

TEST(Drone, CloudMapsOntoTrueSurfacesThroughTrueSimilarity) {
  const auto& f = fixture();
  const auto& s = f.survey;
  ASSERT_GT(s.cloud.size(), 10000u);
  ASSERT_EQ(s.truth.size(), s.cloud.size());
  ASSERT_EQ(s.cloud.labels, s.truth);
  ASSERT_EQ(s.cloud.colors.size(), s.cloud.size());
  const auto world = world_points(s, s.T_world_sfm);
  std::size_t checked = 0, on_surface = 0, label_agrees = 0, stone_points = 0;
  for (std::size_t i = 0; i < world.size(); i += 7) {
    const auto d = surface_distances(f.site, world[i]);
    const auto own = static_cast<std::size_t>(s.truth[i] + 1);
    ASSERT_LT(own, d.size());
    ++checked;
    stone_points += s.truth[i] >= 0;
    on_surface += d[own] <= kTolerance;
    label_agrees += d[own] <= *std::min_element(d.begin(), d.end()) + 0.005;
  }
  const double on = double(on_surface) / double(checked), agree = double(label_agrees) / double(checked);
  std::printf("drone: %zu points, checked %zu (%zu on stones): %.2f %% within %.0f cm, labels %.2f %%\n",
              s.cloud.size(), checked, stone_points, 100 * on, 100 * kTolerance, 100 * agree);
  EXPECT_GE(on, 0.95);
  EXPECT_GE(agree, 0.95);
  EXPECT_GT(stone_points, checked / 20);

  // A 5 % error in scale (about the region centre) no longer fits the stones.
  const Vector3d c(f.config.center_x, f.config.center_y, f.site.terrain.height(f.config.center_x, f.config.center_y));
  const Similarity wrong = Similarity{1.05, Eigen::Matrix3d::Identity(), c - 1.05 * c} * s.T_world_sfm;
  const auto world_wrong = world_points(s, wrong);
  std::size_t on_wrong = 0, on_right = 0, checked_stone = 0;
  for (std::size_t i = 0; i < world_wrong.size(); i += 7) {
    if (s.truth[i] < 0) continue;
    const auto own = static_cast<std::size_t>(s.truth[i] + 1);
    ++checked_stone;
    on_wrong += surface_distances(f.site, world_wrong[i])[own] <= kTolerance;
    on_right += surface_distances(f.site, world[i])[own] <= kTolerance;
  }
  std::printf("drone: stone points on their mesh: %.1f %% (true similarity), %.1f %% (scale 5 %% off)\n",
              100.0 * double(on_right) / double(checked_stone), 100.0 * double(on_wrong) / double(checked_stone));
  EXPECT_LT(double(on_wrong) / double(checked_stone), 0.7);
}

TEST(Drone, OccludedTerrainUnderStonesIsMissing) {
  const auto& f = fixture();
  const auto& s = f.survey;
  const auto world = world_points(s, s.T_world_sfm);
  // Terrain points whose surroundings (0.25 m in every horizontal direction) are all roofed by a
  // stone lie deep under it: no camera at >= 40° elevation sees them.
  const auto roofed = [&](double x, double y) {
    const Vector3d o(x, y, f.site.terrain.height(x, y) + 0.03);
    const RayHit h = f.scene.intersect(Ray{o.cast<float>(), Eigen::Vector3f::UnitZ()});
    return h.hit() && h.label >= 0;
  };
  std::size_t deep = 0, terrain = 0;
  for (std::size_t i = 0; i < world.size(); ++i) {
    if (s.truth[i] >= 0) continue;
    ++terrain;
    const Vector3d& p = world[i];
    bool all = roofed(p.x(), p.y());
    for (int k = 0; all && k < 8; ++k) {
      const double a = k * std::numbers::pi / 4;
      all = roofed(p.x() + 0.25 * std::cos(a), p.y() + 0.25 * std::sin(a));
    }
    deep += all;
  }
  EXPECT_GT(terrain, 1000u);
  EXPECT_EQ(deep, 0u);
  // And there is such a region to miss: terrain grid cells under stones exist.
  std::size_t roofed_cells = 0;
  for (double x = -2; x <= 2; x += 0.05)
    for (double y = -2; y <= 2; y += 0.05) roofed_cells += roofed(x, y);
  EXPECT_GT(roofed_cells, 100u);
}

TEST(Drone, DensityDiffersFromLidar) {
  const auto& s = fixture().survey;
  std::vector<Vec3f> pts(s.cloud.size());
  for (std::size_t i = 0; i < pts.size(); ++i) pts[i] = (s.T_world_sfm * s.cloud.world(i)).cast<float>();
  const KdTree tree(pts);
  Neighbors nn;
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < pts.size(); i += 5, ++n) {
    tree.knn(pts[i], 2, nn);
    sum += std::sqrt(nn.sq_dists[1]);
  }
  const double spacing = sum / double(n);
  std::printf("drone: mean nearest-neighbour spacing %.2f cm (LiDAR voxel: 3 cm)\n", 100 * spacing);
  EXPECT_GT(spacing, 0.010);
  EXPECT_LT(spacing, 0.025);
}

TEST(Drone, EveryPointSeenByTwoCameras) {
  const auto& f = fixture();
  const auto& s = f.survey;
  const auto world = world_points(s, s.T_world_sfm);
  const auto& k = s.camera;
  ASSERT_EQ(s.views.size(), s.cloud.size());
  std::size_t checked = 0, visible = 0;
  for (std::size_t i = 0; i < world.size(); i += 11) {
    ASSERT_NE(s.views[i][0], s.views[i][1]);
    bool ok = true;
    for (const auto a : s.views[i]) {
      ASSERT_LT(a, s.images.size());
      const auto& T = s.images[a].T_world_cam;
      const Vector3d x = T.inverse() * world[i];
      const double u = k.fx * x.x() / x.z() + k.cx, v = k.fy * x.y() / x.z() + k.cy;
      ok = ok && x.z() > 0 && u > -2 && u < k.width + 2 && v > -2 && v < k.height + 2;
      // The first surface along the ray from the camera is at the point (up to the noise).
      const Vector3d d = world[i] - T.translation();
      const RayHit h = f.scene.intersect(Ray{T.translation().cast<float>(), d.normalized().cast<float>()});
      ok = ok && h.hit() && std::abs(h.t - d.norm()) < 0.06;
    }
    ++checked;
    visible += ok;
  }
  EXPECT_GE(double(visible) / double(checked), 0.98) << visible << " of " << checked;
}

TEST(Drone, SimilarityIsWhatTheCamerasAndCloudShow) {
  const auto& f = fixture();
  const auto& s = f.survey;
  const auto& S = s.T_sfm_world;
  EXPECT_GE(S.scale, 0.2);
  EXPECT_LE(S.scale, 5.0);
  EXPECT_NEAR(S.rotation.determinant(), 1.0, 1e-12);
  const Similarity I = s.T_world_sfm * S;
  EXPECT_NEAR(I.scale, 1.0, 1e-12);
  EXPECT_LT((I.rotation - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT(I.translation.norm(), 1e-9);
  EXPECT_GT(rotation_angle(S.rotation), 0.05);  // not gravity-aligned by chance

  // SfM camera centres (C = -R^T t) vs the true ones: Umeyama gives the true similarity.
  const auto n = static_cast<Eigen::Index>(s.images.size());
  Eigen::Matrix3Xd world(3, n), sfm(3, n), vins(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& im = s.images[static_cast<std::size_t>(i)];
    world.col(i) = im.T_world_cam.translation();
    sfm.col(i) = im.position_sfm;
    vins.col(i) = im.position_vins;
    const Eigen::Matrix3d R = im.q_cam_sfm.toRotationMatrix();
    EXPECT_LT((-(R.transpose() * im.t_cam_sfm) - im.position_sfm).norm(), 1e-9 * (1 + im.position_sfm.norm()));
  }
  const Eigen::Matrix4d fit = Eigen::umeyama(world, sfm, true);
  const Similarity F = Similarity::from_matrix(fit);
  EXPECT_NEAR(F.scale / S.scale, 1.0, 0.005);
  EXPECT_LT(rotation_angle(F.rotation.transpose() * S.rotation), 0.005);

  // The terrain in the SfM cloud is tilted by R: its plane normal is R times the world one.
  std::vector<std::uint32_t> terrain;
  for (std::uint32_t i = 0; i < s.cloud.size(); ++i)
    if (s.truth[i] < 0) terrain.push_back(i);
  const auto plane = fit_plane(s.cloud.points, terrain);
  ASSERT_TRUE(plane.has_value());
  // The truth at the same places: the terrain height under each cloud point.
  std::vector<Vec3f> truth_terrain;
  for (const auto i : terrain) {
    const Vector3d w = s.T_world_sfm * s.cloud.world(i);
    truth_terrain.emplace_back(float(w.x()), float(w.y()), float(f.site.terrain.height(w.x(), w.y())));
  }
  std::vector<std::uint32_t> all(truth_terrain.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  const auto truth_plane = fit_plane(truth_terrain, all);
  ASSERT_TRUE(truth_plane.has_value());
  const Vector3d expected = S.rotation * truth_plane->normal.cast<double>();
  EXPECT_LT(std::acos(std::min(1.0, std::abs(expected.dot(plane->normal.cast<double>())))), 0.005);
}

TEST(Drone, SfmAndVinsCameraPositionsRelateByTheTrueSimilarity) {
  const auto& s = fixture().survey;
  const auto n = static_cast<Eigen::Index>(s.images.size());
  Eigen::Matrix3Xd sfm(3, n), vins(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    sfm.col(i) = s.images[static_cast<std::size_t>(i)].position_sfm;
    vins.col(i) = s.images[static_cast<std::size_t>(i)].position_vins;
  }
  // Scale recovery (Sec. 4.1): the similarity from SfM camera centres to VINS positions.
  const Similarity fit = Similarity::from_matrix(Eigen::umeyama(sfm, vins, true));
  const Similarity truth = Similarity::from_isometry(s.T_vins_world) * s.T_world_sfm;
  std::printf("drone: %zu images; SfM->VINS scale %.5f (true %.5f), rotation error %.3f deg\n", s.images.size(),
              fit.scale, truth.scale, rotation_angle(fit.rotation.transpose() * truth.rotation) * 180 / std::numbers::pi);
  EXPECT_NEAR(fit.scale / truth.scale, 1.0, 0.02);
  EXPECT_LT(rotation_angle(fit.rotation.transpose() * truth.rotation), 0.02);
  double rms = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) rms += (fit * Vector3d(sfm.col(i)) - truth * Vector3d(sfm.col(i))).squaredNorm();
  EXPECT_LT(std::sqrt(rms / double(n)), 0.15);
  // VINS is gravity-aligned: its rotation from the world is a pure yaw.
  EXPECT_LT((s.T_vins_world.linear() * Vector3d::UnitZ() - Vector3d::UnitZ()).norm(), 1e-12);
  // Timestamps increase along the flight.
  for (std::size_t i = 1; i < s.images.size(); ++i) EXPECT_GT(s.images[i].timestamp, s.images[i - 1].timestamp);
}

bool same_bytes(const DroneSurvey& a, const DroneSurvey& b) {
  const auto eq = [](const auto& x, const auto& y) {
    return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0;
  };
  if (!eq(a.cloud.points, b.cloud.points) || !eq(a.cloud.colors, b.cloud.colors) || !eq(a.truth, b.truth) ||
      !eq(a.views, b.views) || a.images.size() != b.images.size())
    return false;
  for (std::size_t i = 0; i < a.images.size(); ++i) {
    const auto &p = a.images[i], &q = b.images[i];
    if (p.name != q.name || p.timestamp != q.timestamp || p.q_cam_sfm.coeffs() != q.q_cam_sfm.coeffs() ||
        p.t_cam_sfm != q.t_cam_sfm || p.position_vins != q.position_vins || !p.T_world_cam.isApprox(q.T_world_cam, 0.0))
      return false;
  }
  return a.T_sfm_world.matrix() == b.T_sfm_world.matrix();
}

TEST(Drone, DeterministicForASeedWhateverTheThreads) {
  const auto& f = fixture();
  DroneSurvey serial;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    serial = simulate_drone(f.site, f.scene, f.config, kDroneSeed);
  }
  EXPECT_TRUE(same_bytes(serial, f.survey));
  const auto again = simulate_drone(f.site, f.scene, f.config, kDroneSeed);
  EXPECT_TRUE(same_bytes(again, f.survey));
  const auto other = simulate_drone(f.site, f.scene, f.config, kDroneSeed + 1);
  EXPECT_NE(other.T_sfm_world.scale, f.survey.T_sfm_world.scale);
  std::printf("drone: simulate_drone wall time %.2f s (small test site)\n", again.seconds);
}

TEST(Drone, GravityAlignedOption) {
  const auto& f = fixture();
  DroneConfig c = f.config;
  c.sfm_gravity_aligned = true;
  c.orbit_images = 0;
  c.camera = {.width = 200, .height = 128, .fx = 165.0, .fy = 165.0, .cx = 100.0, .cy = 64.0};
  const auto s = simulate_drone(f.site, f.scene, c, 3);
  EXPECT_LT((s.T_sfm_world.rotation * Vector3d::UnitZ() - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_GT(s.cloud.size(), 1000u);
}

TEST(Drone, ColmapModelAndFiles) {
  const auto& s = fixture().survey;
  const auto dir = test::temp_dir("drone_survey");
  write_drone_survey(dir, s);
  const auto model = io::read_colmap_text(dir / "sparse");
  ASSERT_EQ(model.cameras.size(), 1u);
  EXPECT_EQ(model.cameras[0].model, "PINHOLE");
  ASSERT_EQ(model.images.size(), s.images.size());
  for (std::size_t i = 0; i < s.images.size(); ++i) {
    EXPECT_EQ(model.images[i].name, s.images[i].name);
    EXPECT_LT((model.images[i].center() - s.images[i].position_sfm).norm(), 1e-9 * (1 + s.images[i].position_sfm.norm()));
  }
  EXPECT_GT(model.points.size(), 1000u);
  double error = 0.0;
  for (const auto& p : model.points) {
    ASSERT_GE(p.track.size(), 2u);
    error += p.error;
    for (const auto& t : p.track) {
      const auto& obs = model.images.at(t.image_id - 1).points2d.at(t.point2d_idx);
      EXPECT_EQ(obs.point3d_id, static_cast<std::int64_t>(p.id));
    }
  }
  EXPECT_LT(error / double(model.points.size()), 1.0);  // [px]
  const auto traj = io::read_tum_trajectory(dir / "vins_trajectory.txt");
  ASSERT_EQ(traj.size(), s.images.size());
  EXPECT_EQ(traj[3].position, s.images[3].position_vins);
  const auto cloud = io::load_cloud(dir / "drone_cloud.ply");
  EXPECT_EQ(cloud.size(), s.cloud.size());
  EXPECT_EQ(cloud.labels, s.truth);
  EXPECT_TRUE(std::filesystem::exists(dir / "drone_truth.json"));
}

TEST(Drone, InvalidInputIsAnError) {
  const auto& f = fixture();
  DroneConfig c = f.config;
  c.altitude = -1;
  EXPECT_THROW(simulate_drone(f.site, f.scene, c, 1), ConfigError);
  c = f.config;
  c.sfm_min_scale = 2, c.sfm_max_scale = 1;
  EXPECT_THROW(simulate_drone(f.site, f.scene, c, 1), ConfigError);
  c = f.config;
  c.lawnmower = false, c.orbit_images = 0;
  EXPECT_THROW(simulate_drone(f.site, f.scene, c, 1), ConfigError);
  c = f.config;
  c.point_spacing = 0;
  EXPECT_THROW(simulate_drone(f.site, f.scene, c, 1), ConfigError);
  c = f.config;
  c.camera.fx = std::nan("");
  EXPECT_THROW(simulate_drone(f.site, f.scene, c, 1), ConfigError);
  RayScene uncommitted;
  EXPECT_THROW(simulate_drone(f.site, uncommitted, f.config, 1), InputError);
}

}  // namespace
}  // namespace cairn::sim
