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
#ifndef dcvBatchReport_h
#define dcvBatchReport_h

// What dcv batch tells: an outcome per item, the summary table and CSV, and the progress on stderr.
#include "dcvBatchItems.h"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <sys/ioctl.h>
#include <unistd.h>
#include <vector>

namespace dcv::tools
{

/** What became of an item: a row of the summary. */
struct Outcome
{
  std::string                  status{ "failed: not run" };
  std::string                  reason{ "not run" }; // of a failure
  bool                         failed{ true };
  std::optional<int64_t>       slices;
  std::optional<std::uint64_t> bytes;
  std::optional<double>        ratio; // original bytes (voxels x pixel size) / .dcv bytes
  std::optional<double>        psnr;
  double                       seconds{ 0.0 };
};

/** v with `digits` digits after the point. */
std::string
Fixed(double v, int digits);

/** The summary as CSV (`path`, written atomically): a row per item. */
void
WriteSummaryCsv(const std::string & path, const std::vector<Item> & items, const std::vector<Outcome> & outcomes);

/** The summary as a table on stdout. */
void
PrintSummaryTable(const std::vector<Item> & items, const std::vector<Outcome> & outcomes);

/** Progress on stderr: on a terminal one line refreshed ("batch: i/N items, current NAME P%"), else a
 * plain line per item finished; nothing when quiet. Called from every worker. */
class BatchProgress
{
public:
  BatchProgress(std::size_t total, unsigned workers, bool quiet)
    : m_Terminal(!quiet && ::isatty(2))
    , m_Plain(!quiet && !m_Terminal)
    , m_Total(total)
    , m_Current(workers)
  {}

  void
  Started(unsigned worker, const std::string & name)
  {
    const std::lock_guard<std::mutex> lock(m_Mutex);
    m_Current[worker] = { name, 0 };
    Draw();
  }

  void
  Fraction(unsigned worker, double fraction)
  {
    const std::lock_guard<std::mutex> lock(m_Mutex);
    const int                         percent = int(fraction * 100.0);
    if (percent == m_Current[worker].second)
    {
      return;
    }
    m_Current[worker].second = percent;
    // At most 10 redraws a second: several workers over a slow terminal (ssh) would flood it.
    const auto now = std::chrono::steady_clock::now();
    if (now - m_LastDraw >= std::chrono::milliseconds(100))
    {
      Draw();
    }
  }

  void
  Finished(unsigned worker, const std::string & name, const Outcome & o)
  {
    const std::lock_guard<std::mutex> lock(m_Mutex);
    ++m_Done;
    m_Current[worker] = { "", -1 };
    if (m_Plain)
    {
      std::ostringstream line;
      line << "batch: [" << m_Done << "/" << m_Total << "] " << name << ": " << o.status;
      if (o.bytes && o.psnr)
      {
        line << " (" << *o.bytes << " bytes, ratio " << Fixed(*o.ratio, 1) << ", " << Fixed(*o.psnr, 2) << " dB, "
             << Fixed(o.seconds, 2) << " s)";
      }
      std::cerr << line.str() << std::endl;
    }
    Draw();
  }

  /** Clears the terminal line. */
  void
  Done()
  {
    if (m_Terminal)
    {
      std::fprintf(stderr, "\r\033[K");
      std::fflush(stderr);
    }
  }

private:
  void
  Draw()
  {
    if (!m_Terminal)
    {
      return;
    }
    std::ostringstream line;
    line << "batch: " << m_Done << "/" << m_Total << " items";
    const char * separator = ", current ";
    for (const auto & [name, percent] : m_Current)
    {
      if (!name.empty())
      {
        line << separator << name << " " << percent << "%";
        separator = ", ";
      }
    }
    std::string text = line.str();
    winsize     size{};
    if (::ioctl(2, TIOCGWINSZ, &size) == 0 && size.ws_col > 1 && text.size() >= size.ws_col)
    {
      text.resize(size.ws_col - 1); // a line that wraps cannot be redrawn with \r
    }
    std::fprintf(stderr, "\r%s\033[K", text.c_str());
    m_LastDraw = std::chrono::steady_clock::now();
    std::fflush(stderr);
  }

  const bool                               m_Terminal;
  const bool                               m_Plain;
  const std::size_t                        m_Total;
  std::size_t                              m_Done{ 0 };
  std::vector<std::pair<std::string, int>> m_Current; // per worker: item and percent
  std::chrono::steady_clock::time_point    m_LastDraw;
  std::mutex                               m_Mutex;
};

} // namespace dcv::tools

#endif
