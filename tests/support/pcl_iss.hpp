#pragma once
// pcl::ISSKeypoint3D set up with cairn's IssConfig, for the peer tests and benchmarks (PCL is
// never linked by the library).
#include <pcl/keypoints/iss_3d.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include "cairn/features/iss.hpp"

namespace cairn::test {

using PclIss = pcl::ISSKeypoint3D<pcl::PointXYZ, pcl::PointXYZ>;

/// Radii, thresholds and minimum neighbours as `cfg`, a kd-tree search, `threads` OpenMP threads.
inline void configure_pcl_iss(PclIss& iss, const IssConfig& cfg, unsigned threads = 2) {
  iss.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  iss.setSalientRadius(cfg.salient_radius);
  iss.setNonMaxRadius(cfg.non_max_radius);
  iss.setThreshold21(cfg.gamma_21);
  iss.setThreshold32(cfg.gamma_32);
  iss.setMinNeighbors(cfg.min_neighbors);
  iss.setNumberOfThreads(threads);
}

}  // namespace cairn::test
