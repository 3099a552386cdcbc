// A message delivered twice is recognised by its source, sequence number and
// time; a restarted sender (numbers again from the start, at later times) is
// not a repeat; memory is bounded.
#include <gtest/gtest.h>

#include "bus/repeat_filter.hpp"

namespace vslam::bus {
namespace {

TEST(RepeatFilter, TheSameMessageTwiceIsARepeatAnotherSourceOrTimeIsNot) {
  RepeatFilter f;
  EXPECT_FALSE(f.repeated("forward", 7, 1000));
  EXPECT_TRUE(f.repeated("forward", 7, 1000));
  EXPECT_FALSE(f.repeated("backward", 7, 1000)) << "another camera's seq 7";
  EXPECT_FALSE(f.repeated("forward", 7, 99000)) << "a restarted sender's seq 7, later";
  EXPECT_FALSE(f.repeated("forward", 6, 1000 - 1)) << "late (reordered), not seen before";
  EXPECT_TRUE(f.repeated("forward", 6, 1000 - 1));
  EXPECT_EQ(f.repeats(), 2);
}

TEST(RepeatFilter, RemembersOnlyTheLastCapacityMessages) {
  RepeatFilter f(4);
  for (int64_t seq = 1; seq <= 5; ++seq) EXPECT_FALSE(f.repeated("c", seq, seq * 10));
  EXPECT_FALSE(f.repeated("c", 1, 10)) << "forgotten: five messages ago with room for four";
  EXPECT_TRUE(f.repeated("c", 5, 50));
}

}  // namespace
}  // namespace vslam::bus
