/*=========================================================================
 *
 *  Copyright NumFOCUS
 *
 *  Licensed under the Apache License, Version 2.0 (the "License");
 *  you may not use this file except in compliance with the License.
 *  You may obtain a copy of the License at
 *
 *         http://www.apache.org/licenses/LICENSE-2.0.txt
 *
 *  Unless required by applicable law or agreed to in writing, software
 *  distributed under the License is distributed on an "AS IS" BASIS,
 *  WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
 *  See the License for the specific language governing permissions and
 *  limitations under the License.
 *
 *=========================================================================*/
// The progress of dcv compress: a bar with the time left on a terminal, plain lines in a log once a job
// has run a while, the terminal line cleared at the end.
#include "dcvProgress.h"

#include <gtest/gtest.h>

using dcv::tools::ProgressMeter;

TEST(Progress, TerminalShowsABarThePercentageAndTheTimeLeft)
{
  ProgressMeter m("compressing", true);
  EXPECT_EQ(m.Update(0.0, 0.0), "\rcompressing [" + std::string(30, ' ') + "] 0%\033[K");
  // No pace yet (under a second): no estimate.
  EXPECT_EQ(m.Update(0.1, 0.5), "\rcompressing [###" + std::string(27, ' ') + "] 10%\033[K");
  // A quarter done in 10 s: 30 s left.
  EXPECT_EQ(m.Update(0.25, 10.0), "\rcompressing [#######" + std::string(23, ' ') + "] 25%, 0:30 left\033[K");
  EXPECT_EQ(m.Update(0.25, 10.0), "") << "nothing changed: nothing is redrawn";
  EXPECT_EQ(m.Update(0.5, 3000.0),
            "\rcompressing [" + std::string(15, '#') + std::string(15, ' ') + "] 50%, 50:00 left\033[K");
  EXPECT_EQ(m.Update(1.0, 6000.0), "\r\033[K") << "the line is cleared for the summary";
  EXPECT_EQ(m.Update(1.0, 6001.0), "");
}

TEST(Progress, LogsGetAPlainLineAtEachTenthOfALongJobOnly)
{
  ProgressMeter m("compressing", false);
  EXPECT_EQ(m.Update(0.0, 0.0), "");
  EXPECT_EQ(m.Update(0.35, 5.0), "") << "a short job stays silent";
  EXPECT_EQ(m.Update(0.5, 10.0), "compressing: 50% after 0:10, about 0:10 left\n");
  EXPECT_EQ(m.Update(0.55, 11.0), "");
  EXPECT_EQ(m.Update(0.6, 12.0), "compressing: 60% after 0:12, about 0:08 left\n");
  EXPECT_EQ(m.Update(0.6, 13.0), "");
  EXPECT_EQ(m.Update(1.0, 4000.0), "compressing: 100% after 1:06:40\n");
}

TEST(Progress, TheTimeLeftCountsFromTheFirstReport)
{
  // The encoder's first report ends a stage of a fixed share (I*: 20%) whatever it took: 3 s here.
  ProgressMeter m("compressing", false);
  EXPECT_EQ(m.Update(0.2, 3.0), "");
  // 40% more in 10 s: 40% left, 10 s (from the start it would read 13 x 0.4 / 0.6, 0:09).
  EXPECT_EQ(m.Update(0.6, 13.0), "compressing: 60% after 0:13, about 0:10 left\n");
  ProgressMeter skipped("compressing", true);
  EXPECT_EQ(skipped.Update(0.25, 0.03), "\rcompressing [#######" + std::string(23, ' ') + "] 25%\033[K");
  // A quarter in 20 s since the first report: half left, 40 s (from the start it would read 0:20).
  EXPECT_EQ(skipped.Update(0.5, 20.03),
            "\rcompressing [" + std::string(15, '#') + std::string(15, ' ') + "] 50%, 0:40 left\033[K");
}

TEST(Progress, DurationsReadAsClockTimes)
{
  EXPECT_EQ(ProgressMeter::Duration(0.0), "0:00");
  EXPECT_EQ(ProgressMeter::Duration(59.6), "1:00");
  EXPECT_EQ(ProgressMeter::Duration(3599.0), "59:59");
  EXPECT_EQ(ProgressMeter::Duration(3600.0), "1:00:00");
  EXPECT_EQ(ProgressMeter::Duration(-5.0), "0:00");
}
