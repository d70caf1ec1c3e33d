// fit_scale (registration/scale_check.hpp): the check that tells a wrongly scaled source from the
// matched segments, on known answers.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cairn/core/error.hpp"
#include "cairn/registration/scale_check.hpp"

namespace cairn {
namespace {

constexpr float kA = 0.45f, kB = 0.35f, kC = 0.3f;  // the boulders' semi-axes [m]

/// Six boulders spread over an 8 m site (what matched segments look like), each sampled on its
/// visible upper half (an ellipsoid cap, ~0.9 x 0.7 x 0.6 m) every few cm with noise; `normals`
/// gets the ellipsoid's outward normals when given.
std::vector<std::vector<Vec3f>> boulders(std::uint64_t seed, std::vector<std::vector<Vec3f>>* normals = nullptr) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.005f);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const Vec3f centres[] = {{-3.0f, -2.5f, 0.3f}, {2.5f, -3.0f, 0.3f}, {0.5f, 3.0f, 0.3f},
                           {-3.2f, 2.2f, 0.3f},  {3.4f, 1.0f, 0.3f},  {0.0f, 0.2f, 0.3f}};
  std::vector<std::vector<Vec3f>> out;
  for (const Vec3f& c : centres) {
    std::vector<Vec3f> stone;
    for (int i = 0; i < 3000; ++i) {
      const float phi = 6.2831853f * u(rng), cos_t = u(rng);  // upper hemisphere
      const float sin_t = std::sqrt(1.0f - cos_t * cos_t);
      const Vec3f e(kA * sin_t * std::cos(phi), kB * sin_t * std::sin(phi), kC * cos_t);
      stone.push_back(c + e + Vec3f(noise(rng), noise(rng), noise(rng)));
      if (normals) {
        if (normals->size() < out.size() + 1) normals->emplace_back();
        normals->back().push_back(Vec3f(e.x() / (kA * kA), e.y() / (kB * kB), e.z() / (kC * kC)).normalized());
      }
    }
    out.push_back(std::move(stone));
  }
  return out;
}

/// Pairs of the boulders: the source's scaled by k about `about` (the rest of a rigid fit's error
/// is a shift), the target's as they are, with their normals when `with_normals` (point-to-plane,
/// as register_global passes them).
std::vector<SegmentPair> pairs(float k, const Vec3f& about, bool with_normals = false) {
  std::vector<std::vector<Vec3f>> normals;
  const auto source = boulders(2), target = boulders(1, &normals);
  std::vector<SegmentPair> out(source.size());
  for (std::size_t s = 0; s < source.size(); ++s) {
    for (const Vec3f& p : source[s]) out[s].source.push_back(about + k * (p - about));
    out[s].target = target[s];
    if (with_normals) out[s].target_normals = normals[s];
  }
  return out;
}

TEST(ScaleCheck, TheRightScaleFitsOne) {
  const ScaleFit fit = fit_scale(pairs(1.0f, Vec3f::Zero()));
  EXPECT_TRUE(fit.observable);
  EXPECT_EQ(fit.segments, 6u);
  EXPECT_GT(fit.extent, 3.0);
  EXPECT_NEAR(fit.scale, 1.0, 1e-3);
}

TEST(ScaleCheck, RecoversScaleErrorsOfOneToTenPercentBothWays) {
  for (const bool point_to_plane : {false, true})
    for (const float k : {0.90f, 0.95f, 0.98f, 0.99f, 1.01f, 1.02f, 1.05f, 1.10f}) {
      const ScaleFit fit = fit_scale(pairs(k, {0.7f, -0.4f, 0.0f}, point_to_plane));
      EXPECT_TRUE(fit.observable) << k;
      EXPECT_NEAR(fit.scale * k, 1.0, 2e-3)
          << (point_to_plane ? "point-to-plane" : "point-to-point") << ", source scaled by " << k << ": fitted " << fit.scale;
    }
}

TEST(ScaleCheck, ASegmentPairedWithAPieceOfItsStoneIsAnOutlier) {
  // The target's segment 5 is the half of its stone facing -x (a stone the LiDAR split or saw
  // from one side): its own alignment moves the source's whole stone by decimetres.
  for (const float k : {1.0f, 1.05f}) {
    std::vector<SegmentPair> p = pairs(k, {0.7f, -0.4f, 0.0f});
    std::vector<Vec3f> half;
    for (const Vec3f& q : p[5].target)
      if (q.x() < 0.0f) half.push_back(q);
    p[5].target = half;
    const ScaleFit fit = fit_scale(p);
    EXPECT_TRUE(fit.observable);
    EXPECT_EQ(fit.segments, 5u) << k;
    EXPECT_NEAR(fit.scale * k, 1.0, 2e-3) << "source scaled by " << k << ": fitted " << fit.scale;
  }
}

TEST(ScaleCheck, FewOrCloseSegmentsAreNotObservableAndBadInputIsRefused) {
  std::vector<SegmentPair> two = pairs(1.05f, Vec3f::Zero());
  two.resize(3);
  EXPECT_FALSE(fit_scale(two).observable);  // fewer than min_segments (4)
  const ScaleFit close = fit_scale(pairs(1.05f, Vec3f::Zero()), {.min_extent = 10.0});
  EXPECT_FALSE(close.observable);  // spread over less than min_extent: no verdict
  std::vector<SegmentPair> bad = pairs(1.0f, Vec3f::Zero());
  bad[1].source[5].x() = std::nanf("");
  EXPECT_THROW((void)fit_scale(bad), InputError);
  std::vector<SegmentPair> partial = pairs(1.0f, Vec3f::Zero(), true);
  partial[2].target_normals.pop_back();  // normals for some points only
  EXPECT_THROW((void)fit_scale(partial), InputError);
  EXPECT_THROW((void)fit_scale(two, {.max_scale_error = 0.0}), ConfigError);
}

}  // namespace
}  // namespace cairn
