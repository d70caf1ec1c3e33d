#pragma once
// Ray casting against the static world (terrain and stones) with Embree 3. One RayScene is built
// per world state; after commit() any number of threads may cast rays concurrently.
#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>

#include "cairn/core/io/io.hpp"

namespace cairn::sim {

struct Ray {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  Eigen::Vector3f direction = Eigen::Vector3f::UnitX();  // need not be unit length
  float t_near = 0.0f;
  float t_far = std::numeric_limits<float>::infinity();  // in units of |direction|
};

struct RayHit {
  static constexpr std::int32_t kNoLabel = std::numeric_limits<std::int32_t>::min();
  /// Ray parameter of the first hit (distance when the direction is a unit vector); +inf if none.
  float t = std::numeric_limits<float>::infinity();
  std::int32_t label = kNoLabel;  // the label of the mesh that was hit
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();  // unit geometric normal, facing the ray
  [[nodiscard]] bool hit() const { return t < std::numeric_limits<float>::infinity(); }
};

class RayScene {
 public:
  RayScene();
  ~RayScene();
  RayScene(RayScene&&) noexcept;
  RayScene& operator=(RayScene&&) noexcept;
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  /// Adds a triangle mesh (world frame: vertices + mesh.origin) whose hits report `label`.
  /// Throws InputError on an empty mesh or out-of-range indices; LogicError-like InputError when
  /// called after commit().
  void add_mesh(const io::Mesh& mesh, std::int32_t label);
  /// Builds the acceleration structure; afterwards the scene is immutable.
  void commit();
  [[nodiscard]] bool committed() const;

  [[nodiscard]] RayHit intersect(const Ray& ray) const;
  /// Casts many rays in parallel (TBB); hits[i] belongs to rays[i].
  void intersect(std::span<const Ray> rays, std::span<RayHit> hits) const;
  /// Whether anything lies on the ray between t_near and t_far.
  [[nodiscard]] bool occluded(const Ray& ray) const;

  [[nodiscard]] std::size_t num_triangles() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cairn::sim
