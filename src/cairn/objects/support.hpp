#pragma once
// Which stored object rests on which (beyond the paper, issue #21: clearing a pile). The paper
// picks the largest stone first (Sec. 5.1) on sites where the stones lie apart; on a pile a stone
// that others lean on must not go first, or the pile collapses onto the gripper. Decided from the
// database's clouds alone (what the machine sees), never from the simulator's truth.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/objects/object_db.hpp"
#include "cairn/objects/support_config.hpp"

namespace cairn {

/// One contact between two objects: `upper` rests on `lower` when `rests`.
struct Contact {
  std::size_t lower = 0, upper = 0;  // indices into the objects given
  std::size_t points = 0;            // points of both within contact_distance of the other
  Vec3d at = Vec3d::Zero();          // the contact points' mean (world)
  double elevation_deg = 0.0;        // of `at` seen from the lower object's centroid
  bool rests = false;
};

/// Every pair of touching objects (each pair once, `upper` the one with the higher centroid).
[[nodiscard]] std::vector<Contact> contacts(std::span<const ObjectRecord> objects, const SupportConfig& c);

/// Per object, how many others rest on it (from `contacts`).
[[nodiscard]] std::vector<int> loads(std::size_t n, std::span<const Contact> contacts);

/// The index of the object to pick next among `candidates` (indices into `objects`): one that no
/// other object of `objects` rests on, the largest (most points, Sec. 5.1) of those. The relation
/// follows the centroids' heights, so the highest object always is free; when every candidate
/// carries another (the free ones are no candidates), the candidate with the highest centroid.
/// `candidates` must not be empty.
[[nodiscard]] std::size_t next_to_pick(std::span<const ObjectRecord> objects, std::span<const std::size_t> candidates,
                                       const SupportConfig& c);

}  // namespace cairn
