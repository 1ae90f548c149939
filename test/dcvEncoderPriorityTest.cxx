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
// The encoder's threads keep the process's priority (the encoder fits beside other work). The
// corners' layer's thread once lowered its own (nice 19) to give way to the points' parallel parts; beside
// other busy processes of the same login it then starved while rate control waited for it (the 5 mm CT
// series at 0.125 bpv 203 s instead of 8 s beside two busy loops: docs/profile.md).
#include "dcvTestUtilities.h"
#include "itkDCVEncoder.h"

#include <algorithm>
#include <exception>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#if defined(__linux__)
#  include <sys/resource.h>
#endif

namespace
{
#if defined(__linux__)
/** The largest nice value among the process's threads now (/proc/self/task/ * /stat, field 19). */
int
HighestThreadNice()
{
  int highest = -20;
  for (const auto & task : std::filesystem::directory_iterator("/proc/self/task"))
  {
    // A thread that ends between the listing and the read makes the read fail (ESRCH), which
    // libstdc++'s stream buffer reports by throwing: such a thread has no priority to check.
    std::string stat;
    try
    {
      std::ifstream in(task.path() / "stat");
      stat.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    catch (const std::exception &)
    {
      continue;
    }
    const auto end = stat.rfind(')'); // after the command's name, which may hold spaces
    if (end == std::string::npos)
      continue;                                      // the thread ended meanwhile
    std::istringstream fields(stat.substr(end + 1)); // from field 3 (the state) on
    std::string        field;
    for (int i = 3; i < 19; ++i)
      fields >> field;
    int nice = 0;
    if (fields >> nice)
      highest = std::max(highest, nice);
  }
  return highest;
}
#endif
} // namespace

TEST(EncoderPriority, EveryThreadKeepsTheProcessPriority)
{
#if !defined(__linux__)
  GTEST_SKIP() << "thread priorities are read from /proc";
#else
  const int process = getpriority(PRIO_PROCESS, 0);
  // A budget with a residual layer, coded on its own thread while the points report their progress.
  const auto          image = dcv::test::PhantomImage({ 96, 96, 96 });
  dcv::EncoderOptions options;
  options.bitsPerVoxel = 0.1;
  options.threads = 2;
  int reports = 0;
  int highest = -20;
  options.progress = [&](double) {
    ++reports;
    highest = std::max(highest, HighestThreadNice());
  };
  const auto r = itk::DCVEncode(image.GetPointer(), options);
  EXPECT_GT(r.bytes.size(), 0u);
  EXPECT_GT(reports, 10);
  EXPECT_EQ(highest, process) << "a thread of the encoder ran at a lower priority than the process";
#endif
}
