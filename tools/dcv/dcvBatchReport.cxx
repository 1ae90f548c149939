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
#include "dcvBatchReport.h"
#include "dcvTools.h"

#include <algorithm>
#include <iomanip>
#include <iostream>

namespace dcv::tools
{
std::string
Fixed(double v, int digits)
{
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

namespace
{
/** The cells of a row: item, slices, bytes, ratio, PSNR, seconds, status (`digits` more for the CSV). */
std::vector<std::string>
Cells(const std::string & name, const Outcome & o, int digits)
{
  return { name,
           o.slices ? std::to_string(*o.slices) : "",
           o.bytes ? std::to_string(*o.bytes) : "",
           o.ratio ? Fixed(*o.ratio, 1 + digits) : "",
           o.psnr ? Fixed(*o.psnr, 2 + digits) : "",
           Fixed(o.seconds, 2 + digits),
           o.status };
}

const std::vector<std::string> Columns{ "item", "slices", "bytes", "ratio", "PSNR", "seconds", "status" };

std::string
CsvField(const std::string & s)
{
  if (s.find_first_of(",\"\n") == std::string::npos)
  {
    return s;
  }
  std::string quoted = "\"";
  for (char c : s)
  {
    quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  }
  return quoted + "\"";
}
} // namespace

void
WriteSummaryCsv(const std::string & path, const std::vector<Item> & items, const std::vector<Outcome> & outcomes)
{
  std::ostringstream csv;
  for (std::size_t c = 0; c < Columns.size(); ++c)
  {
    csv << (c ? "," : "") << Columns[c];
  }
  csv << "\n";
  for (std::size_t i = 0; i < items.size(); ++i)
  {
    const auto cells = Cells(items[i].name, outcomes[i], 2);
    for (std::size_t c = 0; c < cells.size(); ++c)
    {
      csv << (c ? "," : "") << CsvField(cells[c]);
    }
    csv << "\n";
  }
  const std::string text = csv.str();
  WriteFileAtomically(path, std::vector<uint8_t>(text.begin(), text.end()));
}

void
PrintSummaryTable(const std::vector<Item> & items, const std::vector<Outcome> & outcomes)
{
  std::vector<std::vector<std::string>> rows{ Columns };
  for (std::size_t i = 0; i < items.size(); ++i)
  {
    rows.push_back(Cells(items[i].name, outcomes[i], 0));
    std::string & status = rows.back().back();
    if (status.size() > 80) // the whole reason is on stderr and in the CSV; the table stays readable
    {
      status = status.substr(0, 77) + "...";
    }
  }
  std::vector<std::size_t> width(Columns.size(), 0);
  for (const auto & row : rows)
  {
    for (std::size_t c = 0; c < row.size(); ++c)
    {
      width[c] = std::max(width[c], row[c].size());
    }
  }
  for (const auto & row : rows)
  {
    std::ostringstream line;
    for (std::size_t c = 0; c < row.size(); ++c)
    {
      const bool last = c + 1 == row.size();
      // Names and statuses to the left, numbers to the right.
      line << (c == 0 || last ? std::left : std::right) << std::setw(last ? 0 : int(width[c])) << row[c]
           << (last ? "" : "  ");
    }
    std::cout << line.str() << "\n";
  }
  std::cout.flush();
}

} // namespace dcv::tools
