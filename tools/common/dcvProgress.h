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
#ifndef dcvProgress_h
#define dcvProgress_h

// The progress of one long job (dcv compress, dcv approximate) on stderr.
#include <functional>
#include <string>

namespace dcv::tools
{

/** What the progress of one job looks like, from the fraction done and the seconds since it started:
 * on a terminal a bar, the percentage and an estimate of the time left (from the pace since the first
 * report), redrawn in place; elsewhere (a log, a pipe) a plain line at each tenth, once the job has run
 * PlainAfterSeconds (short jobs stay silent). Separate from the clock and the stream so that tests can
 * drive it. */
class ProgressMeter
{
public:
  static constexpr double PlainAfterSeconds = 10.0;
  static constexpr int    BarWidth = 30;

  ProgressMeter(std::string label, bool terminal);

  /** What to write for this report ("" when nothing visible changed). At 1 on a terminal: the line is
   * cleared, for the job's own summary. */
  std::string
  Update(double fraction, double seconds);

  /** "m:ss" (or "h:mm:ss"). */
  static std::string
  Duration(double seconds);

private:
  std::string m_Label;
  bool        m_Terminal;
  std::string m_Last;       // the last line drawn on the terminal
  int         m_Tenth{ 0 }; // the last tenth reported in plain lines
  bool        m_Cleared{ false };
  bool        m_Started{ false }; // the first report's fraction and seconds: where the pace counts from
  double      m_FirstFraction{ 0.0 };
  double      m_FirstSeconds{ 0.0 };
};

/** A progress function for EncoderOptions::progress showing a ProgressMeter on stderr (a terminal when
 * stderr is one); an empty function when `quiet`. */
std::function<void(double)>
ProgressOutput(const std::string & label, bool quiet);

} // namespace dcv::tools

#endif
