#pragma once
// The one voxel hash of cairn: a flat open-addressing hash map (linear probing, power-of-two
// capacity, at most half full — it grows by rehashing) from packed integer 3-D cell coordinates
// to a 32-bit value. Behind the neighbour searches that scan the cells around a point
// (clustering, splitting, columns), the local map's voxel index, the drone's fusion cells and the
// levelling's sign cells.
#include <cstdint>
#include <limits>
#include <vector>

namespace cairn {

class CellMap {
 public:
  static constexpr std::uint32_t kAbsent = std::numeric_limits<std::uint32_t>::max();

  /// Capacity for `expected` entries at a load factor of at most 1/2 (more entries grow it).
  explicit CellMap(std::size_t expected = 0) { allocate(expected); }

  /// Packs cell coordinates (each within ±2^20) into one key (never the empty slot's).
  static std::uint64_t key(std::int64_t x, std::int64_t y, std::int64_t z) {
    constexpr std::int64_t kBias = std::int64_t{1} << 20;
    constexpr std::uint64_t kMask = (std::uint64_t{1} << 21) - 1;
    return (std::uint64_t(z + kBias) & kMask) << 42 | (std::uint64_t(y + kBias) & kMask) << 21 |
           (std::uint64_t(x + kBias) & kMask);
  }

  /// Inserts key → value unless present; returns the stored value (== value: it was new).
  /// Grows only for a new key (a key already present never rehashes a half-full map).
  std::uint32_t insert(std::uint64_t k, std::uint32_t value) {
    if (keys_.empty()) allocate(0);  // moved from
    std::size_t s = slot(k);
    for (; keys_[s] != kEmpty; s = (s + 1) & mask_)
      if (keys_[s] == k) return values_[s];
    if (2 * (size_ + 1) > keys_.size()) {
      grow();
      return insert(k, value);  // once: the grown map has room
    }
    keys_[s] = k;
    values_[s] = value;
    ++size_;
    return value;
  }

  [[nodiscard]] std::uint32_t find(std::uint64_t k) const {
    if (keys_.empty()) return kAbsent;  // moved from
    for (std::size_t s = slot(k);; s = (s + 1) & mask_) {
      if (keys_[s] == k) return values_[s];
      if (keys_[s] == kEmpty) return kAbsent;
    }
  }

  [[nodiscard]] std::size_t size() const { return size_; }
  /// Slots allocated (a power of two, at least twice the entries).
  [[nodiscard]] std::size_t capacity() const { return keys_.size(); }

  /// Empty, with capacity for `expected` entries.
  void clear(std::size_t expected = 0) { allocate(expected); }

 private:
  static constexpr std::uint64_t kEmpty = std::numeric_limits<std::uint64_t>::max();
  static constexpr std::size_t kMinCapacity = 16;

  void allocate(std::size_t expected) {
    std::size_t cap = kMinCapacity;
    while (cap < 2 * expected) cap *= 2;
    keys_.assign(cap, kEmpty);
    values_.assign(cap, kAbsent);
    mask_ = cap - 1;
    size_ = 0;
  }

  void grow() {
    std::vector<std::uint64_t> keys = std::move(keys_);
    std::vector<std::uint32_t> values = std::move(values_);
    allocate(keys.size());  // twice the entries the old capacity held
    for (std::size_t i = 0; i < keys.size(); ++i)
      if (keys[i] != kEmpty) insert(keys[i], values[i]);
  }

  [[nodiscard]] std::size_t slot(std::uint64_t k) const {
    k ^= k >> 33;  // splitmix-style finaliser
    k *= 0xff51afd7ed558ccdull;
    k ^= k >> 33;
    return std::size_t(k) & mask_;
  }
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> values_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace cairn
