#pragma once
// The newest cloud received on a topic (a map, a drone cloud), shared between the subscriber
// callbacks and the services of a node's core: set() replaces it, get() hands out the current one
// without copying it (C++20 side of the ROS layer).
#include <memory>
#include <mutex>

#include "cairn_ros/convert.hpp"

namespace cairn::bag {

class LatestCloud {
 public:
  void set(const file::Cloud& c) {
    auto cloud = std::make_shared<const PointCloud>(points_of(c));
    const std::lock_guard lock(mutex_);
    cloud_ = std::move(cloud);
  }
  void reset() {
    const std::lock_guard lock(mutex_);
    cloud_.reset();
  }
  /// The newest cloud; null before the first (an empty cloud counts as none).
  [[nodiscard]] std::shared_ptr<const PointCloud> get() const {
    const std::lock_guard lock(mutex_);
    return cloud_ && !cloud_->empty() ? cloud_ : nullptr;
  }

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const PointCloud> cloud_;
};

}  // namespace cairn::bag
