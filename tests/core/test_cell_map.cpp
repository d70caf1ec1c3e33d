// CellMap (core/cell_map.hpp), the one voxel hash: exact round-trips through growth, the first
// value of a key kept, absent keys, no growth for a present key, a moved-from map, and distinct
// keys for neighbouring and negative cells.
#include <gtest/gtest.h>

#include <random>
#include <set>
#include <utility>

#include "cairn/core/cell_map.hpp"

namespace cairn::cell_map_test {

TEST(CellMap, KeepsEveryEntryWhileGrowingFromEmpty) {
  CellMap map;  // no expected size: grows from the minimum
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> coord(-200000, 200000);
  std::vector<std::uint64_t> keys;
  std::set<std::uint64_t> seen;
  while (keys.size() < 50000) {
    const std::uint64_t k = CellMap::key(coord(rng), coord(rng), coord(rng));
    if (seen.insert(k).second) keys.push_back(k);
  }
  for (std::size_t i = 0; i < keys.size(); ++i) EXPECT_EQ(map.insert(keys[i], std::uint32_t(i)), std::uint32_t(i));
  EXPECT_EQ(map.size(), keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) ASSERT_EQ(map.find(keys[i]), std::uint32_t(i));
  // A second insert of a key returns the stored value and changes nothing.
  EXPECT_EQ(map.insert(keys[7], 999999u), 7u);
  EXPECT_EQ(map.size(), keys.size());
  EXPECT_EQ(map.find(CellMap::key(300000, 0, 0)), CellMap::kAbsent);
  map.clear();
  EXPECT_EQ(map.size(), 0u);
  EXPECT_EQ(map.find(keys[0]), CellMap::kAbsent);
}

TEST(CellMap, AKeyAlreadyPresentNeverGrowsAHalfFullMap) {
  CellMap map(8);  // 16 slots: the 8th entry fills it to half
  for (int i = 0; i < 8; ++i) map.insert(CellMap::key(i, 0, 0), std::uint32_t(i));
  ASSERT_EQ(map.capacity(), 16u);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(map.insert(CellMap::key(i, 0, 0), 99u), std::uint32_t(i));
  EXPECT_EQ(map.capacity(), 16u);  // re-inserting present keys: no rehash
  EXPECT_EQ(map.insert(CellMap::key(8, 0, 0), 8u), 8u);  // a new key: grows
  EXPECT_EQ(map.capacity(), 32u);
  for (int i = 0; i <= 8; ++i) EXPECT_EQ(map.find(CellMap::key(i, 0, 0)), std::uint32_t(i));
  // A moved-from map answers "absent" and takes new keys.
  CellMap moved = std::move(map);
  EXPECT_EQ(moved.find(CellMap::key(3, 0, 0)), 3u);
  EXPECT_EQ(map.find(CellMap::key(3, 0, 0)), CellMap::kAbsent);  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(map.insert(CellMap::key(3, 0, 0), 5u), 5u);
  EXPECT_EQ(map.find(CellMap::key(3, 0, 0)), 5u);
}

TEST(CellMap, NeighbouringAndNegativeCellsHaveDistinctKeys) {
  std::set<std::uint64_t> keys;
  for (int x = -2; x <= 2; ++x)
    for (int y = -2; y <= 2; ++y)
      for (int z = -2; z <= 2; ++z) keys.insert(CellMap::key(x, y, z));
  EXPECT_EQ(keys.size(), 125u);
  const std::int64_t edge = (std::int64_t{1} << 20) - 1;  // the packing's range: ±2^20
  EXPECT_NE(CellMap::key(edge, 0, 0), CellMap::key(-edge, 0, 0));
  EXPECT_NE(CellMap::key(-(std::int64_t{1} << 20), 0, 0), CellMap::key(0, 0, 0));
}

}  // namespace cairn::cell_map_test
