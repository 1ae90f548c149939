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
#include "dcvProgress.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <utility>

#include <unistd.h>

namespace dcv::tools
{

ProgressMeter::ProgressMeter(std::string label, bool terminal)
  : m_Label(std::move(label))
  , m_Terminal(terminal)
{}

std::string
ProgressMeter::Duration(double seconds)
{
  const long s = std::lround(std::max(0.0, seconds));
  char       text[32];
  if (s >= 3600)
    std::snprintf(text, sizeof(text), "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  else
    std::snprintf(text, sizeof(text), "%ld:%02ld", s / 60, s % 60);
  return text;
}

std::string
ProgressMeter::Update(double fraction, double seconds)
{
  fraction = std::clamp(fraction, 0.0, 1.0);
  const int percent = int(fraction * 100.0);
  // The time left from the pace since the first report: the encoder's first is the end of a stage of
  // its own (I*, given a fixed share whether it took 3 s or was skipped in 0.03 s), whose share would
  // bias a pace taken from the start (norm-256 at 0.25 bpv: 0:28 left shown where 1:00 was). Shown
  // once there is a pace to go by (2% and one second since).
  if (!m_Started)
  {
    m_Started = true;
    m_FirstFraction = fraction;
    m_FirstSeconds = seconds;
  }
  std::string  left;
  const double done = fraction - m_FirstFraction, elapsed = seconds - m_FirstSeconds;
  if (done >= 0.02 && fraction < 1.0 && elapsed >= 1.0)
    left = Duration(elapsed * (1.0 - fraction) / done);
  if (m_Terminal)
  {
    if (m_Cleared)
      return "";
    if (percent >= 100)
    {
      m_Cleared = true;
      return "\r\033[K";
    }
    const int   filled = int(fraction * BarWidth);
    std::string line = m_Label + " [" + std::string(std::size_t(filled), '#') +
                       std::string(std::size_t(BarWidth - filled), ' ') + "] " + std::to_string(percent) + "%";
    line += left.empty() ? "" : ", " + left + " left";
    if (line == m_Last)
      return "";
    m_Last = line;
    return "\r" + line + "\033[K";
  }
  const int tenth = int(fraction * 10.0);
  if (tenth <= m_Tenth || seconds < PlainAfterSeconds)
    return "";
  m_Tenth = tenth;
  std::string line = m_Label + ": " + std::to_string(tenth * 10) + "% after " + Duration(seconds);
  line += left.empty() ? "" : ", about " + left + " left";
  return line + "\n";
}

std::function<void(double)>
ProgressOutput(const std::string & label, bool quiet)
{
  if (quiet)
    return {};
  struct State
  {
    explicit State(const std::string & label)
      : meter(label, ::isatty(2) != 0)
    {}
    ProgressMeter                         meter;
    std::chrono::steady_clock::time_point start{ std::chrono::steady_clock::now() };
    std::mutex                            mutex; // the encoder may report from its threads
  };
  auto state = std::make_shared<State>(label);
  return [state](double fraction) {
    const std::lock_guard<std::mutex> lock(state->mutex);
    const double      seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - state->start).count();
    const std::string text = state->meter.Update(fraction, seconds);
    if (!text.empty())
    {
      std::fputs(text.c_str(), stderr);
      std::fflush(stderr);
    }
  };
}

} // namespace dcv::tools
