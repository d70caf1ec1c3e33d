#pragma once
// A flat open-addressing hash map from integer 3-D cell coordinates to a 32-bit value — the
// voxel hash behind neighbour searches that scan the cells around a point.
#include <cstdint>
#include <limits>
#include <vector>

namespace cairn {

class CellMap {
 public:
  static constexpr std::uint32_t kAbsent = std::numeric_limits<std::uint32_t>::max();

  /// Capacity for `expected` entries at a load factor of at most 1/2.
  explicit CellMap(std::size_t expected) {
    std::size_t cap = 16;
    while (cap < 2 * expected) cap *= 2;
    keys_.assign(cap, kEmpty);
    values_.assign(cap, kAbsent);
    mask_ = cap - 1;
  }

  /// Packs cell coordinates (each within ±2^20) into one key.
  static std::uint64_t key(std::int64_t x, std::int64_t y, std::int64_t z) {
    constexpr std::int64_t kBias = std::int64_t{1} << 20;
    constexpr std::uint64_t kMask = (std::uint64_t{1} << 21) - 1;
    return (std::uint64_t(z + kBias) & kMask) << 42 | (std::uint64_t(y + kBias) & kMask) << 21 |
           (std::uint64_t(x + kBias) & kMask);
  }

  /// Inserts key → value unless present; returns the stored value.
  std::uint32_t insert(std::uint64_t k, std::uint32_t value) {
    for (std::size_t s = slot(k);; s = (s + 1) & mask_) {
      if (keys_[s] == k) return values_[s];
      if (keys_[s] == kEmpty) {
        keys_[s] = k;
        values_[s] = value;
        return value;
      }
    }
  }

  [[nodiscard]] std::uint32_t find(std::uint64_t k) const {
    for (std::size_t s = slot(k);; s = (s + 1) & mask_) {
      if (keys_[s] == k) return values_[s];
      if (keys_[s] == kEmpty) return kAbsent;
    }
  }

 private:
  static constexpr std::uint64_t kEmpty = std::numeric_limits<std::uint64_t>::max();
  [[nodiscard]] std::size_t slot(std::uint64_t k) const {
    k ^= k >> 33;  // splitmix-style finaliser
    k *= 0xff51afd7ed558ccdull;
    k ^= k >> 33;
    return std::size_t(k) & mask_;
  }
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> values_;
  std::size_t mask_ = 0;
};

}  // namespace cairn
