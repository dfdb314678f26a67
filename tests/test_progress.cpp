// The CLI's progress lines: elapsed time and the time left at the rate so far (app/progress.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "progress.hpp"

using lambert::app::format_duration;
using lambert::app::progress_due;
using lambert::app::kProgressHeartbeat;
using lambert::app::progress_timing;

// Exact strings: users read them, scripts may too.
TEST(Progress, DurationsReadAsSecondsMinutesOrHours) {
  EXPECT_EQ(format_duration(0), "0.0 s");
  EXPECT_EQ(format_duration(4.27), "4.2 s");
  EXPECT_EQ(format_duration(9.99), "9.9 s");
  EXPECT_EQ(format_duration(10), "10 s");
  EXPECT_EQ(format_duration(59.99), "59 s");
  EXPECT_EQ(format_duration(60), "1 min 00 s");
  EXPECT_EQ(format_duration(185.5), "3 min 05 s");
  EXPECT_EQ(format_duration(3599), "59 min 59 s");
  EXPECT_EQ(format_duration(3600), "1 h 00 min");
  EXPECT_EQ(format_duration(4320), "1 h 12 min");
  EXPECT_EQ(format_duration(-3), "0.0 s");
  EXPECT_EQ(format_duration(NAN), "0.0 s");
}

// The time left is the elapsed time scaled by what is left over what is done: 25 % done in 60 s leaves 180 s. Not
// before 3 s or 1 % (the rate is not known yet), and not at the end.
TEST(Progress, TimeLeftIsTheRateSoFarExtrapolated) {
  EXPECT_EQ(progress_timing(0.25, 60), "1 min 00 s, about 3 min 00 s left");
  EXPECT_EQ(progress_timing(0.5, 10), "10 s, about 10 s left");
  EXPECT_EQ(progress_timing(0.03, 4), "4.0 s, about 2 min 09 s left");  // 4 * 0.97 / 0.03 = 129.3 s
  EXPECT_EQ(progress_timing(0.5, 2.9), "2.9 s");  // too early to say
  EXPECT_EQ(progress_timing(0.005, 100), "1 min 40 s");  // too little done to say
  EXPECT_EQ(progress_timing(1.0, 95), "1 min 35 s");   // finished: the phase's time
}

// On a terminal a line at most every 0.1 s; in a log one per tenth of the work, and one a minute while a tenth takes
// longer (exact udales_shape.obj printed nothing for minutes after "0%").
TEST(Progress, LogGetsALineEachTenthAndAtLeastOneAMinute) {
  EXPECT_TRUE(progress_due(true, 0, 0, 0.1));
  EXPECT_FALSE(progress_due(true, 5, 0, 0.05));
  EXPECT_TRUE(progress_due(false, 1, 0, 0.01));   // a new tenth
  EXPECT_FALSE(progress_due(false, 0, 0, 59.9));  // same tenth, within the minute
  EXPECT_TRUE(progress_due(false, 0, 0, kProgressHeartbeat));
  EXPECT_EQ(kProgressHeartbeat, 60);
}
