#include "cairn/core/point_cloud.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <cmath>
#include <limits>

#include "cairn/core/error.hpp"

namespace cairn {

const ScalarField* PointCloud::field(const std::string& name) const {
  for (const auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

ScalarField* PointCloud::field(const std::string& name) {
  for (auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

void PointCloud::check_consistent(const std::string& what) const {
  const auto n = points.size();
  auto check = [&](std::size_t m, const char* attr) {
    if (m != 0 && m != n)
      throw InputError(what + ": attribute '" + attr + "' has " + std::to_string(m) +
                       " entries for " + std::to_string(n) + " points");
  };
  check(normals.size(), "normals");
  check(colors.size(), "colors");
  check(times.size(), "times");
  check(labels.size(), "labels");
  for (const auto& f : fields) check(f.values.size(), f.name.c_str());
}

void PointCloud::check_finite(const std::string& what) const {
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite())
      throw InputError(what + ": point " + std::to_string(i) +
                       " has a non-finite coordinate (NaN or Inf)");
  }
  if (!origin.allFinite()) throw InputError(what + ": origin is not finite");
}

void PointCloud::reserve(std::size_t n) { points.reserve(n); }

PointCloud select(const PointCloud& cloud, std::span<const std::uint32_t> indices) {
  PointCloud out;
  out.origin = cloud.origin;
  const auto pick = [&](const auto& src, auto& dst) {
    if (src.empty()) return;
    dst.reserve(indices.size());
    for (auto i : indices) dst.push_back(src[i]);
  };
  pick(cloud.points, out.points);
  pick(cloud.normals, out.normals);
  pick(cloud.colors, out.colors);
  pick(cloud.times, out.times);
  pick(cloud.labels, out.labels);
  for (const auto& f : cloud.fields) {
    ScalarField g{f.name, {}};
    pick(f.values, g.values);
    out.fields.push_back(std::move(g));
  }
  return out;
}

std::vector<std::uint32_t> remove_non_finite(PointCloud& cloud) {
  std::vector<std::uint32_t> kept;
  kept.reserve(cloud.size());
  for (std::uint32_t i = 0; i < cloud.size(); ++i)
    if (cloud.points[i].allFinite()) kept.push_back(i);
  if (kept.size() != cloud.size()) cloud = select(cloud, kept);
  return kept;
}

void append(PointCloud& a, const PointCloud& b) {
  if (a.empty()) {
    a = b;
    return;
  }
  const auto na = a.size();
  const Vec3f shift = (b.origin - a.origin).cast<float>();
  a.points.reserve(na + b.size());
  for (const auto& p : b.points) a.points.push_back(p + shift);
  const auto merge = [&](auto& dst, const auto& src) {
    if (dst.empty() || src.empty()) {
      dst.clear();
      return;
    }
    dst.insert(dst.end(), src.begin(), src.end());
  };
  merge(a.normals, b.normals);
  merge(a.colors, b.colors);
  merge(a.times, b.times);
  merge(a.labels, b.labels);
  std::vector<ScalarField> fields;
  for (auto& f : a.fields)
    if (const auto* g = b.field(f.name)) {
      f.values.insert(f.values.end(), g->values.begin(), g->values.end());
      fields.push_back(std::move(f));
    }
  a.fields = std::move(fields);
}

Aabb bounds(std::span<const Vec3f> points) {
  constexpr std::size_t kGrain = 16384;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, points.size(), kGrain), Aabb{},
      [&](const tbb::blocked_range<std::size_t>& r, Aabb box) {
        for (auto i = r.begin(); i != r.end(); ++i) {
          box.min = box.min.cwiseMin(points[i]);
          box.max = box.max.cwiseMax(points[i]);
        }
        return box;
      },
      [](Aabb a, const Aabb& b) {
        a.min = a.min.cwiseMin(b.min);
        a.max = a.max.cwiseMax(b.max);
        return a;
      });
}

Vec3f centroid(std::span<const Vec3f> points) {
  Vec3d sum = Vec3d::Zero();
  for (const auto& p : points) sum += p.cast<double>();
  return points.empty() ? Vec3f::Zero() : Vec3f((sum / double(points.size())).cast<float>());
}

Vec3f centroid(std::span<const Vec3f> points, std::span<const std::uint32_t> indices) {
  Vec3d sum = Vec3d::Zero();
  for (auto i : indices) sum += points[i].cast<double>();
  return indices.empty() ? Vec3f::Zero() : Vec3f((sum / double(indices.size())).cast<float>());
}

}  // namespace cairn
