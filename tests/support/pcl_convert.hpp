#pragma once
// cairn points and normals as PCL clouds, for the peer cross-checks and benchmarks (PCL is never
// linked by the library).
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <limits>
#include <span>

#include "cairn/core/point_cloud.hpp"

namespace cairn::test {

using PclXyz = pcl::PointCloud<pcl::PointXYZ>;

inline PclXyz::Ptr to_pcl(std::span<const Vec3f> pts) {
  auto c = pcl::make_shared<PclXyz>();
  c->reserve(pts.size());
  for (const auto& p : pts) c->push_back({p.x(), p.y(), p.z()});
  return c;
}

/// cairn's "no normal" (zero vector) is PCL's NaN normal.
inline pcl::PointCloud<pcl::Normal>::Ptr to_pcl_normals(std::span<const Vec3f> normals) {
  auto c = pcl::make_shared<pcl::PointCloud<pcl::Normal>>();
  c->reserve(normals.size());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const auto& n : normals) {
    pcl::Normal q;
    if (n.isZero(0.0f))
      q.normal_x = q.normal_y = q.normal_z = nan;
    else
      q.getNormalVector3fMap() = n;
    c->push_back(q);
  }
  return c;
}

}  // namespace cairn::test
