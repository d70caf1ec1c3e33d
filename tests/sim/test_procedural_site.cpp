// Procedural stone site: mesh helpers, stone generation and placement, LiDAR-like sampling.
#include "cairn/sim/procedural_site.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cairn/core/error.hpp"
#include "cairn/sim/simulation.hpp"
#include "support/mesh_distance.hpp"
#include "support/sanitizers.hpp"

namespace cairn::sim {
namespace {

using Eigen::Vector3d;

constexpr std::uint64_t kSiteSeeds[] = {1, 2, 3, 42, 2024};
constexpr std::uint64_t kSampleSeeds[] = {1, 42, 2024};

/// Unit cube [0,1]^3 shifted by `offset`, stored relative to `origin`; outward triangles.
io::Mesh unit_cube(const Vector3d& offset = Vector3d::Zero(),
                   const Vector3d& origin = Vector3d::Zero()) {
  io::Mesh mesh;
  mesh.vertices.origin = origin;
  for (int i = 0; i < 8; ++i) {
    const Vector3d corner(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    mesh.vertices.points.push_back((corner + offset - origin).cast<float>());
  }
  mesh.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return mesh;
}

Vector3d vertex(const io::Mesh& mesh, std::uint32_t i) { return mesh.vertices.world(i); }

/// Closed and consistently oriented: every directed edge appears once, its reverse once.
bool closed_and_oriented(const io::Mesh& mesh) {
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (const auto& [a, b, c] : mesh.triangles)
    for (const auto& e : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}})
      if (!edges.insert(e).second) return false;
  return std::all_of(edges.begin(), edges.end(), [&](const auto& e) {
    return edges.count({e.second, e.first}) == 1;
  });
}

Eigen::AlignedBox3d mesh_box(const io::Mesh& mesh) {
  Eigen::AlignedBox3d box;
  for (std::uint32_t i = 0; i < mesh.vertices.size(); ++i) box.extend(vertex(mesh, i));
  return box;
}

const Site& site_for(std::uint64_t seed) {
  static std::map<std::uint64_t, Site> cache;
  auto it = cache.find(seed);
  if (it == cache.end()) it = cache.emplace(seed, generate_site({}, seed)).first;
  return it->second;
}

const SampledSite& sampled_for(std::uint64_t seed) {
  static std::map<std::uint64_t, SampledSite> cache;
  auto it = cache.find(seed);
  if (it == cache.end()) it = cache.emplace(seed, sample_site(site_for(seed), {}, seed)).first;
  return it->second;
}

// --- mesh helpers ----------------------------------------------------------------------------

TEST(MeshVolume, UnitCube) {
  EXPECT_NEAR(mesh_volume(unit_cube()), 1.0, 1e-6);
  // Georeferenced: positions relative to a far origin.
  const Vector3d offset(5.0e5, 4.0e6, 300.0);
  EXPECT_NEAR(mesh_volume(unit_cube(offset, offset)), 1.0, 1e-6);
  EXPECT_TRUE(mesh_centroid(unit_cube(offset, offset)).isApprox(offset + Vector3d::Constant(0.5)));
}

TEST(MeshVolume, IcosphereMatchesSphere) {
  const double r = 0.7;
  io::Mesh sphere = make_icosphere(4);
  for (auto& p : sphere.vertices.points) p *= static_cast<float>(r);
  EXPECT_TRUE(closed_and_oriented(sphere));
  EXPECT_EQ(sphere.triangles.size(), 20u * 256u);
  const double exact = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  EXPECT_NEAR(mesh_volume(sphere), exact, 0.01 * exact);
  EXPECT_LT(mesh_volume(sphere), exact);  // inscribed polyhedron
  EXPECT_LT(mesh_centroid(sphere).norm(), 1e-6);
}

TEST(InsideMesh, Cube) {
  const io::Mesh cube = unit_cube();
  for (const Vector3d& p : {Vector3d(0.5, 0.5, 0.5), Vector3d(0.1, 0.9, 0.2),
                            Vector3d(0.99, 0.01, 0.98), Vector3d(0.3, 0.7, 0.05)})
    EXPECT_TRUE(inside_mesh(cube, p)) << p.transpose();
  for (const Vector3d& p :
       {Vector3d(1.5, 0.5, 0.5), Vector3d(0.5, 0.5, -0.1), Vector3d(0.5, 0.5, 1.2),
        Vector3d(-0.01, 0.3, 0.3), Vector3d(0.3, 1.01, 0.3), Vector3d(5, 5, 5)})
    EXPECT_FALSE(inside_mesh(cube, p)) << p.transpose();
  const Vector3d offset(5.0e5, 4.0e6, 300.0);
  EXPECT_TRUE(inside_mesh(unit_cube(offset, offset), offset + Vector3d(0.4, 0.6, 0.5)));
  EXPECT_FALSE(inside_mesh(unit_cube(offset, offset), offset + Vector3d(0.4, 0.6, 1.5)));
}

TEST(InsideMesh, IcosphereAgreesWithRadius) {
  const SolidMesh solid(make_icosphere(3));
  std::mt19937_64 rng(7);
  int checked = 0;
  for (int n = 0; n < 20'000; ++n) {
    Vector3d p;
    for (int d = 0; d < 3; ++d) p[d] = 2.4 * uniform01(rng) - 1.2;
    const double r = p.norm();
    if (r > 0.99 && r < 1.0) continue;  // between the inscribed faces and the sphere
    EXPECT_EQ(solid.contains(p), r < 0.99) << p.transpose();
    ++checked;
  }
  EXPECT_GT(checked, 19'000);
}

TEST(InsideMesh, RaysThroughVerticesAndEdgesCountOnce) {
  const io::Mesh sphere = make_icosphere(3);
  const SolidMesh solid(sphere);
  const auto check = [&](const Vector3d& q) {
    const double r = q.head<2>().norm();
    if (r > 0.95) return;
    EXPECT_TRUE(solid.contains(Vector3d(q.x(), q.y(), 0.0))) << q.transpose();
    if (r > 0.3) {  // below the lower surface: the ray meets it and the upper one
      EXPECT_FALSE(solid.contains(Vector3d(q.x(), q.y(), -0.9999))) << q.transpose();
    }
  };
  for (std::uint32_t v = 0; v < sphere.vertices.size(); ++v) check(vertex(sphere, v));
  for (const auto& [a, b, c] : sphere.triangles) {
    check(0.5 * (vertex(sphere, a) + vertex(sphere, b)));  // exactly on the projected edge
    check(0.5 * (vertex(sphere, b) + vertex(sphere, c)));
  }
}

TEST(StoneMesh, ExactVolumeCentredClosed) {
  std::mt19937_64 rng(11);
  for (int n = 0; n < 10; ++n) {
    const bool flat = n % 2 == 1;
    const double target = 0.5 + 0.05 * n;
    const io::Mesh stone = make_stone_mesh(target, flat, rng);
    EXPECT_NEAR(mesh_volume(stone), target, 0.01 * target);
    EXPECT_LT(mesh_centroid(stone).norm(), 1e-5);
    EXPECT_TRUE(closed_and_oriented(stone));
    EXPECT_GE(stone.triangles.size(), 640u);
    EXPECT_TRUE(inside_mesh(stone, Vector3d::Zero()));
    const Vector3d size = mesh_box(stone).sizes();
    EXPECT_LT(size.z(), size.head<2>().maxCoeff());  // shortest axis vertical
    if (flat) {
      EXPECT_LT(size.minCoeff() / size.maxCoeff(), 0.5);
    }
  }
}

TEST(StoneMesh, IrregularNotEllipsoid) {
  // Fracture cuts leave planar facets: many vertices share a plane. An ellipsoid has none.
  std::mt19937_64 rng(5);
  const io::Mesh stone = make_stone_mesh(0.8, false, rng);
  int best = 0;
  for (std::size_t t = 0; t < stone.triangles.size(); t += 4) {
    const auto& [i, j, k] = stone.triangles[t];
    const Vector3d a = vertex(stone, i), n = (vertex(stone, j) - a).cross(vertex(stone, k) - a);
    if (n.norm() < 1e-9) continue;
    int coplanar = 0;
    for (std::uint32_t v = 0; v < stone.vertices.size(); ++v)
      coplanar += std::abs((vertex(stone, v) - a).dot(n.normalized())) < 1e-5 ? 1 : 0;
    best = std::max(best, coplanar);
  }
  EXPECT_GT(best, 15);
}

// --- generated sites -----------------------------------------------------------------------

TEST(GenerateSite, StoneCountsAndVolumes) {
  const StoneConfig config;
  for (auto seed : kSiteSeeds) {
    SCOPED_TRACE(seed);
    const Site& site = site_for(seed);
    ASSERT_EQ(site.stones.size(), static_cast<std::size_t>(config.count));
    int flat = 0;
    for (const auto& stone : site.stones) {
      EXPECT_GE(stone.volume, config.min_volume);
      EXPECT_LE(stone.volume, config.max_volume);
      const double volume = mesh_volume(stone.mesh);
      EXPECT_NEAR(volume, stone.volume, 0.01 * stone.volume);
      EXPECT_GE(volume, config.min_volume * 0.999);
      EXPECT_LE(volume, config.max_volume * 1.001);
      EXPECT_LT((mesh_centroid(stone.mesh) - stone.centroid).norm(), 1e-4);
      EXPECT_LE(stone.centroid.head<2>().norm(), config.placement_radius);
      EXPECT_TRUE(closed_and_oriented(stone.mesh));
      flat += stone.flat ? 1 : 0;
    }
    EXPECT_EQ(flat, static_cast<int>(std::lround(config.flat_fraction * config.count)));
  }
}

/// Whether no vertex of `a` comes horizontally closer than `gap` to a vertex of `b`.
bool keeps_horizontal_gap(const io::Mesh& a, const io::Mesh& b, double gap) {
  // Only vertices within `gap` of the other mesh's xy bounding box can violate the gap.
  const auto near = [gap](const io::Mesh& m, const io::Mesh& other) {
    const Eigen::AlignedBox3d box = mesh_box(other);
    std::vector<Eigen::Vector2d> out;
    for (std::uint32_t v = 0; v < m.vertices.size(); ++v) {
      const Eigen::Vector2d p = vertex(m, v).head<2>();
      if ((p.array() >= box.min().head<2>().array() - gap).all() &&
          (p.array() <= box.max().head<2>().array() + gap).all())
        out.push_back(p);
    }
    return out;
  };
  for (const auto& p : near(a, b))
    for (const auto& q : near(b, a))
      if ((p - q).norm() < gap) return false;
  return true;
}

TEST(GenerateSite, StonesDoNotIntersectAndKeepSpacing) {
  const StoneConfig config;
  for (auto seed : kSiteSeeds) {
    SCOPED_TRACE(seed);
    const auto& stones = site_for(seed).stones;
    for (std::size_t i = 0; i < stones.size(); ++i)
      for (std::size_t j = 0; j < stones.size(); ++j) {
        if (i == j) continue;
        const SolidMesh other(stones[j].mesh);
        int inside = 0;
        for (std::uint32_t v = 0; v < stones[i].mesh.vertices.size(); ++v)
          inside += other.contains(vertex(stones[i].mesh, v)) ? 1 : 0;
        EXPECT_EQ(inside, 0) << "stone " << i << " in stone " << j;
        if (i < j) {
          EXPECT_TRUE(keeps_horizontal_gap(stones[i].mesh, stones[j].mesh, config.min_spacing))
              << "stones " << i << ", " << j;
        }
      }
  }
}

TEST(GenerateSite, LowestPointEmbedDepthBelowTerrain) {
  const StoneConfig config;
  for (auto seed : kSiteSeeds) {
    SCOPED_TRACE(seed);
    const Site& site = site_for(seed);
    for (const auto& stone : site.stones) {
      double lowest = std::numeric_limits<double>::max();
      for (std::uint32_t v = 0; v < stone.mesh.vertices.size(); ++v) {
        const Vector3d p = vertex(stone.mesh, v);
        lowest = std::min(lowest, p.z() - site.terrain.height(p.x(), p.y()));
      }
      EXPECT_NEAR(lowest, -config.embed_depth, 1e-3);
    }
  }
}

TEST(GenerateSite, FlatStonesAreSlabsLyingFlat) {
  for (auto seed : kSiteSeeds) {
    SCOPED_TRACE(seed);
    for (const auto& stone : site_for(seed).stones) {
      if (!stone.flat) continue;
      const Vector3d size = mesh_box(stone.mesh).sizes();
      EXPECT_LT(size.minCoeff() / size.maxCoeff(), 0.5);
      EXPECT_EQ(size.minCoeff(), size.z());
    }
  }
}

TEST(GenerateSite, TerrainIsSmoothAndSloped) {
  const Site& site = site_for(1);
  const TerrainConfig config;
  // Mean slope: the 12 m span dominates the undulations and the gravel.
  const double rise = site.terrain.height(5.0, 0.0) - site.terrain.height(-5.0, 0.0);
  EXPECT_NEAR(rise / 10.0, config.slope_x, 0.1);
  // Normal is the unit upward normal of the height field.
  for (double x : {-3.1, 0.2, 4.7}) {
    const Vector3d n = site.terrain.normal(x, 0.5 * x);
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    EXPECT_GT(n.z(), 0.5);
    const double h = 1e-5;
    const Vector3d tx(2 * h, 0,
                      site.terrain.height(x + h, 0.5 * x) - site.terrain.height(x - h, 0.5 * x));
    EXPECT_NEAR(n.dot(tx.normalized()), 0.0, 1e-3);
  }
}

// Every seed of every scenario makes its site: sequential placement jams now and then (with the
// shipped real meshes exp1 seed 24 and exp2 seeds 8 and 18 could not place their seventh stone),
// and then the stones are drawn again (seeds 1-200 of exp1, exp2 and pile all make their sites:
// 145 s, run once; here the spread scenarios, whose placement can jam, on seeds 1-40).
TEST(GenerateSite, EveryScenarioPlacesItsStonesOnEverySeed) {
  const std::uint64_t last = test::kSanitized ? 8 : 40;
  const std::vector<std::pair<std::string, std::uint64_t>> jammed = {{"exp1", 24}, {"exp2", 8}, {"exp2", 18}};
  for (const std::string name : {"exp1", "exp2"}) {
    const SiteConfig config = scenario_config(name, default_real_mesh_dir()).site;
    std::vector<std::uint64_t> seeds;
    for (std::uint64_t seed = 1; seed <= last; ++seed) seeds.push_back(seed);
    for (const auto& [scenario, seed] : jammed) {
      if (scenario == name && seed > last) seeds.push_back(seed);
    }
    for (const std::uint64_t seed : seeds) {
      SCOPED_TRACE(name + " seed " + std::to_string(seed));
      EXPECT_EQ(generate_site(config, seed).stones.size(), static_cast<std::size_t>(config.stones.count));
    }
  }
}

TEST(GenerateSite, InvalidConfigThrows) {
  SiteConfig config;
  config.stones.count = -1;
  EXPECT_THROW(generate_site(config, 1), ConfigError);
  config = {};
  config.stones.min_volume = 2.0;
  EXPECT_THROW(generate_site(config, 1), ConfigError);
  config = {};
  config.terrain.size_x = 0.0;
  EXPECT_THROW(generate_site(config, 1), ConfigError);
  config = {};
  config.stones.count = 40;  // cannot fit in a 4 m disc with 0.4 m gaps
  EXPECT_THROW(generate_site(config, 1), ConfigError);
  EXPECT_THROW(sample_site(site_for(1), {.spacing = 0.0}, 1), ConfigError);
  EXPECT_THROW(make_icosphere(-1), ConfigError);
  std::mt19937_64 rng(1);
  EXPECT_THROW(make_stone_mesh(0.0, false, rng), ConfigError);
}

// --- sampling --------------------------------------------------------------------------------

TEST(SampleSite, LabelsAndCounts) {
  for (auto seed : kSampleSeeds) {
    SCOPED_TRACE(seed);
    const Site& site = site_for(seed);
    const SampledSite& sampled = sampled_for(seed);
    ASSERT_EQ(sampled.truth.size(), sampled.cloud.size());
    EXPECT_EQ(sampled.cloud.labels, sampled.truth);
    EXPECT_NO_THROW(sampled.cloud.check_consistent());
    EXPECT_NO_THROW(sampled.cloud.check_finite());
    EXPECT_GT(sampled.cloud.size(), 140'000u);
    EXPECT_LT(sampled.cloud.size(), 220'000u);
    std::map<std::int32_t, std::size_t> counts;
    for (auto label : sampled.truth) ++counts[label];
    EXPECT_GT(counts[-1], 140'000u);
    for (std::size_t k = 0; k < site.stones.size(); ++k)
      EXPECT_GT(counts[static_cast<std::int32_t>(k)], 1000u) << "stone " << k;
    EXPECT_EQ(counts.size(), site.stones.size() + 1);  // no other labels
  }
}

TEST(SampleSite, StonePointsLieOnStoneSurfaces) {
  const double sigma = SamplingConfig{}.noise_sigma;
  for (auto seed : kSampleSeeds) {
    SCOPED_TRACE(seed);
    const Site& site = site_for(seed);
    const SampledSite& sampled = sampled_for(seed);
    std::map<std::int32_t, std::vector<std::size_t>> by_stone;
    for (std::size_t i = 0; i < sampled.truth.size(); ++i)
      if (sampled.truth[i] >= 0) by_stone[sampled.truth[i]].push_back(i);
    for (const auto& [k, indices] : by_stone) {
      const test::TriangleSoup surface(site.stones[static_cast<std::size_t>(k)].mesh);
      const std::size_t stride = std::max<std::size_t>(1, indices.size() / 120);
      std::size_t tested = 0, within = 0;
      double worst = 0.0;
      for (std::size_t n = 0; n < indices.size(); n += stride) {
        const double d = surface.distance(sampled.cloud.world(indices[n]));
        within += d <= 4 * sigma ? 1 : 0;
        worst = std::max(worst, d);
        ++tested;
      }
      // Normal-direction noise is N(0, sigma): P(> 4 sigma) = 6e-5 per point.
      EXPECT_GE(static_cast<double>(within), 0.995 * static_cast<double>(tested)) << "stone " << k;
      EXPECT_LT(worst, 6 * sigma) << "stone " << k;
    }
  }
}

TEST(SampleSite, TerrainPointsLieOnTerrain) {
  const double sigma = SamplingConfig{}.noise_sigma;
  for (auto seed : kSampleSeeds) {
    SCOPED_TRACE(seed);
    const Site& site = site_for(seed);
    const SampledSite& sampled = sampled_for(seed);
    std::size_t tested = 0, within = 0;
    double worst = 0.0;
    for (std::size_t i = 0; i < sampled.cloud.size(); i += 3) {
      if (sampled.truth[i] != -1) continue;
      const Vector3d p = sampled.cloud.world(i);
      // Distance along the terrain normal (the vertical offset times cos of the slope angle).
      const double d = std::abs(p.z() - site.terrain.height(p.x(), p.y())) *
                       site.terrain.normal(p.x(), p.y()).z();
      within += d <= 4 * sigma ? 1 : 0;
      worst = std::max(worst, d);
      ++tested;
    }
    EXPECT_GE(static_cast<double>(within), 0.999 * static_cast<double>(tested));
    EXPECT_LT(worst, 6 * sigma);
    EXPECT_GT(tested, 40'000u);
  }
}

TEST(SampleSite, NoTerrainPointsInsideStonesNorStonePointsBuried) {
  const Site& site = site_for(42);
  SamplingConfig noiseless;
  noiseless.noise_sigma = 0.0;
  const SampledSite sampled = sample_site(site, noiseless, 3);
  std::vector<SolidMesh> solids;
  for (const auto& stone : site.stones) solids.emplace_back(stone.mesh);
  for (std::size_t i = 0; i < sampled.cloud.size(); i += 7) {
    const Vector3d p = sampled.cloud.world(i);
    if (sampled.truth[i] >= 0) {
      EXPECT_GE(p.z() - site.terrain.height(p.x(), p.y()), -1e-5);
      continue;
    }
    for (const auto& solid : solids) EXPECT_FALSE(solid.contains(p)) << p.transpose();
  }
}

TEST(SampleSite, TrueNormalsOnRequest) {
  const Site& site = site_for(2);
  SamplingConfig config;
  config.spacing = 0.06;
  config.true_normals = true;
  const SampledSite sampled = sample_site(site, config, 2);
  ASSERT_EQ(sampled.cloud.normals.size(), sampled.cloud.size());
  for (std::size_t i = 0; i < sampled.cloud.size(); i += 101)
    EXPECT_NEAR(sampled.cloud.normals[i].norm(), 1.0f, 1e-4f);
  EXPECT_FALSE(sampled_for(1).cloud.has_normals());
}

TEST(SampleSite, DeterministicForSeed) {
  const Site again = generate_site({}, 42);
  const Site& site = site_for(42);
  ASSERT_EQ(again.stones.size(), site.stones.size());
  for (std::size_t k = 0; k < site.stones.size(); ++k)
    EXPECT_EQ(again.stones[k].mesh.vertices.points, site.stones[k].mesh.vertices.points);

  const SampledSite a = sample_site(again, {}, 42);
  const SampledSite& b = sampled_for(42);
  ASSERT_EQ(a.cloud.size(), b.cloud.size());
  EXPECT_EQ(
      std::memcmp(a.cloud.points.data(), b.cloud.points.data(), a.cloud.size() * sizeof(Vec3f)), 0);
  EXPECT_EQ(a.truth, b.truth);

  const SampledSite other_sampling = sample_site(site, {}, 43);
  EXPECT_NE(other_sampling.cloud.points, b.cloud.points);
  const SampledSite& other_site = sampled_for(2024);
  EXPECT_NE(other_site.cloud.points, b.cloud.points);
  EXPECT_NE(site_for(1).stones[0].centroid, site.stones[0].centroid);
}

TEST(Random, UniformAndNormalMoments) {
  std::mt19937_64 rng(3);
  constexpr int kDraws = 200'000;
  double sum_u = 0, sum_n = 0, sum_n2 = 0;
  for (int i = 0; i < kDraws; ++i) {
    const double u = uniform01(rng);
    ASSERT_TRUE(u >= 0.0 && u < 1.0);
    sum_u += u;
    const double n = standard_normal(rng);
    sum_n += n;
    sum_n2 += n * n;
  }
  EXPECT_NEAR(sum_u / kDraws, 0.5, 0.005);
  EXPECT_NEAR(sum_n / kDraws, 0.0, 0.01);
  EXPECT_NEAR(sum_n2 / kDraws, 1.0, 0.01);
}

}  // namespace
}  // namespace cairn::sim
