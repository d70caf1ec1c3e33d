#pragma once
// The one kd-tree of cairn: nanoflann over a span of positions, no copy of the points.
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

/// Result of a neighbour query: indices into the indexed span and squared distances.
struct Neighbors {
  std::vector<std::uint32_t> indices;
  std::vector<float> sq_dists;
  [[nodiscard]] std::size_t size() const { return indices.size(); }
  void clear() {
    indices.clear();
    sq_dists.clear();
  }
};

/// The smallest float squared distance >= distance² (double): the bound to give nearest_within
/// when the caller keeps its own test of the distance in double precision.
[[nodiscard]] inline float sq_dist_bound(double distance) {
  const double sq = distance * distance;
  const float b = float(sq);
  return double(b) >= sq ? b : std::nextafter(b, std::numeric_limits<float>::infinity());
}

/// Static 3-D kd-tree. The indexed points must outlive the tree and stay unchanged.
/// Queries are const and thread-safe. Points with a NaN or infinite coordinate are never found
/// (no distance to them exists); a non-finite query finds nothing.
class KdTree {
 public:
  static constexpr int kDefaultLeafSize = 16;
  explicit KdTree(std::span<const Vec3f> points, int leaf_size = kDefaultLeafSize);
  ~KdTree();
  KdTree(KdTree&&) noexcept;
  KdTree& operator=(KdTree&&) noexcept;
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  [[nodiscard]] std::size_t size() const { return points_.size(); }
  [[nodiscard]] std::span<const Vec3f> points() const { return points_; }

  /// k nearest neighbours, sorted by distance (fewer if the tree has fewer points).
  void knn(const Vec3f& query, std::size_t k, Neighbors& out) const;
  /// All neighbours with distance < radius; sorted by distance when `sorted`.
  void radius(const Vec3f& query, float radius, Neighbors& out, bool sorted = false) const;
  /// Index of the nearest point; squared distance in *sq_dist (+inf, index 0, when nothing can be
  /// found: no finite point or a non-finite query).
  [[nodiscard]] std::uint32_t nearest(const Vec3f& query, float* sq_dist = nullptr) const;
  /// nearest() when its squared distance is <= max_sq_dist: the same index and distance (ties
  /// included; the pruning keeps a small slack over nanoflann's float rounding of cell bounds);
  /// otherwise +inf in *sq_dist (index 0). The search never descends where nothing
  /// that close can be, so queries with nothing near (the outliers of an ICP, points off an
  /// object) cost little; callers that threshold the distance anyway get the same answers.
  [[nodiscard]] std::uint32_t nearest_within(const Vec3f& query, float max_sq_dist, float* sq_dist = nullptr) const;

  /// Calls f(index, sq_dist) for each neighbour with distance < radius (no allocation).
  template <class F>
  void for_each_in_radius(const Vec3f& query, float radius, F&& f) const;

 private:
  struct Impl;
  void radius_visit(const Vec3f& query, float radius, void* ctx,
                    void (*visit)(void*, std::uint32_t, float)) const;
  std::span<const Vec3f> points_;
  std::unique_ptr<Impl> impl_;
};

template <class F>
void KdTree::for_each_in_radius(const Vec3f& query, float radius, F&& f) const {
  radius_visit(query, radius, &f, [](void* ctx, std::uint32_t i, float d2) {
    (*static_cast<std::remove_reference_t<F>*>(ctx))(i, d2);
  });
}

}  // namespace cairn
