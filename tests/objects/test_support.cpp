// Which object rests on which (objects/support.hpp, issue #21's pick order on a pile) on hand-made
// round stones: one on top of another, two side by side on the ground, and the pick that follows.
#include "cairn/objects/support.hpp"

#include <gtest/gtest.h>

#include "cairn/core/error.hpp"
#include "scene.hpp"

namespace cairn {
namespace {

ObjectRecord object(std::int64_t id, const Vec3d& center, double radius) {
  ObjectRecord r;
  r.id = id;
  r.cloud = test::stone(center, radius, int(20000 * radius * radius));  // ~5 cm spacing, as a map's
  for (std::size_t i = 0; i < r.cloud.size(); ++i) r.centroid += r.cloud.world(i) / double(r.cloud.size());
  r.num_points = r.cloud.size();
  return r;
}

// A big stone on the ground, a small one on top of it, a middle one beside the big one (touching
// it at its side, both on the ground), and one apart.
std::vector<ObjectRecord> heap() {
  return {object(1, {0.0, 0.0, 0.6}, 0.6), object(2, {0.0, 0.0, 1.55}, 0.35),
          object(3, {1.1, 0.0, 0.5}, 0.5 - 0.005), object(4, {5.0, 0.0, 0.45}, 0.45)};
}

TEST(Support, AStoneOnTopRestsAndStonesSideBySideDoNot) {
  const std::vector<ObjectRecord> o = heap();
  const std::vector<Contact> k = contacts(o, {});
  ASSERT_EQ(k.size(), 2u);  // 1-2 and 1-3; 4 touches nothing
  for (const Contact& c : k) {
    if (c.upper == 1) {  // the small stone on the big one
      EXPECT_EQ(c.lower, 0u);
      EXPECT_TRUE(c.rests);
      EXPECT_GT(c.elevation_deg, 80.0);
      EXPECT_NEAR(c.at.z(), 1.2, 0.05);  // where the spheres touch
    } else {  // side by side: the contact near mid height
      EXPECT_EQ(std::min(c.lower, c.upper), 0u);
      EXPECT_EQ(std::max(c.lower, c.upper), 2u);
      EXPECT_FALSE(c.rests);
      EXPECT_LT(std::abs(c.elevation_deg), 15.0);
    }
  }
  EXPECT_EQ(loads(o.size(), k), (std::vector<int>{1, 0, 0, 0}));
}

TEST(Support, TheLargestStoneNothingRestsOnIsPickedFirst) {
  const std::vector<ObjectRecord> o = heap();
  // All four: the big stone carries the small one; the middle one is the largest free stone.
  EXPECT_EQ(next_to_pick(o, std::vector<std::size_t>{0, 1, 2, 3}, {}), 2u);
  // Without the middle one: the small stone on top goes before the big one under it.
  EXPECT_EQ(next_to_pick(o, std::vector<std::size_t>{0, 1, 3}, {}), 3u);  // 4 (apart) is larger than 2
  EXPECT_EQ(next_to_pick(o, std::vector<std::size_t>{0, 1}, {}), 1u);
  // Only the carrying stone is a candidate: it is picked (the top one is not the machine's to take).
  EXPECT_EQ(next_to_pick(o, std::vector<std::size_t>{0}, {}), 0u);
  // Contacts closer than the points' spacing are never seen: nothing rests, the big one goes first.
  EXPECT_EQ(next_to_pick(o, std::vector<std::size_t>{0, 1}, {.contact_distance = 1e-4}), 0u);
}

TEST(Support, BadConfigurationAndNoCandidateAreErrors) {
  const std::vector<ObjectRecord> o = heap();
  EXPECT_THROW((void)contacts(o, {.contact_distance = 0.0}), ConfigError);
  EXPECT_THROW((void)contacts(o, {.min_elevation_deg = 90.0}), ConfigError);
  EXPECT_THROW((void)next_to_pick(o, std::vector<std::size_t>{}, {}), InputError);
  EXPECT_TRUE(contacts(std::vector<ObjectRecord>{}, {}).empty());
}

}  // namespace
}  // namespace cairn
