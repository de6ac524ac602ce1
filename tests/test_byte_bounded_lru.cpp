// The renderer's byte-bounded LRU (renderer/core/byte_bounded_lru.hpp).
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "core/byte_bounded_lru.hpp"

namespace umbra {
namespace {

TEST(ByteBoundedLru, FindMakesAnEntryTheMostRecentlyUsed) {
  ByteBoundedLru<int> lru;
  lru.insert("a", 1, 10);
  lru.insert("b", 2, 10);
  EXPECT_EQ(lru.front().key, "b");
  ASSERT_NE(lru.find("a"), nullptr);
  EXPECT_EQ(lru.front().key, "a");
  EXPECT_EQ(lru.front().value, 1);
  EXPECT_EQ(lru.find("c"), nullptr);
  EXPECT_EQ(lru.bytes(), 20u);
}

TEST(ByteBoundedLru, EvictsLeastRecentlyUsedUntilWithinBytes) {
  ByteBoundedLru<int> lru;
  lru.insert("a", 1, 100);
  lru.insert("b", 2, 300);
  lru.insert("c", 3, 50);
  lru.find("a");  // order now a, c, b
  EXPECT_EQ(lru.evict_to(200, 8), 300u);
  EXPECT_EQ(lru.size(), 2u);
  EXPECT_EQ(lru.bytes(), 150u);
  EXPECT_EQ(lru.find("b"), nullptr);
  EXPECT_NE(lru.find("c"), nullptr);
  EXPECT_EQ(lru.evict_to(150, 8), 0u) << "exactly at the bound stays";
}

TEST(ByteBoundedLru, EvictsBeyondTheEntryCountToo) {
  ByteBoundedLru<int> lru;
  for (int i = 0; i < 5; ++i) lru.insert(std::to_string(i), i, 1);
  lru.evict_to(1000, 3);
  EXPECT_EQ(lru.size(), 3u);
  EXPECT_EQ(lru.find("0"), nullptr);
  EXPECT_EQ(lru.find("1"), nullptr);
  EXPECT_NE(lru.find("4"), nullptr);
}

TEST(ByteBoundedLru, KeepsTheMostRecentEvenWhenItAloneIsOverTheBound) {
  ByteBoundedLru<int> lru;
  lru.insert("small", 1, 10);
  lru.insert("huge", 2, 1000);
  lru.evict_to(100, 8, 1);
  EXPECT_EQ(lru.size(), 1u);
  EXPECT_EQ(lru.front().key, "huge");
  lru.evict_to(100, 8, 0);
  EXPECT_TRUE(lru.empty());
  EXPECT_EQ(lru.bytes(), 0u);
}

TEST(ByteBoundedLru, DestroysWhatItEvicts) {
  ByteBoundedLru<std::shared_ptr<int>> lru;
  auto held = std::make_shared<int>(7);
  std::weak_ptr<int> watch = held;
  lru.insert("a", std::move(held), 10);
  lru.insert("b", std::make_shared<int>(8), 10);
  EXPECT_FALSE(watch.expired());
  lru.evict_to(10, 8);
  EXPECT_TRUE(watch.expired()) << "the least recently used value is destroyed, not merely uncounted";
}

}  // namespace
}  // namespace umbra
