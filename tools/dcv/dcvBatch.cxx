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
// dcv batch: every DICOM series and volume file of a tree into one .dcv file each, N at a time; a rerun
// resumes (valid outputs are kept), and --shard K/N takes a fixed 1/N of the items so that a scheduler
// spreads an archive over machines.
#include "dcvCommand.h"
#include "itkDCVEncoder.h"
#include "itkMetaDataObject.h"
#include "itkMultiThreaderBase.h"
#include "itkObjectFactoryBase.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdio>
#include <iomanip>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <tuple>
#include <sstream>
#include <sys/ioctl.h>
#include <thread>
#include <unistd.h>

namespace fs = std::filesystem;

namespace dcv::tools
{
namespace
{
struct BatchOptions
{
  std::string   tree;
  std::string   output;
  std::string   unused; // the INPUT of AddMethodOptions, replaced by INPUT_TREE
  MethodOptions method;
  unsigned      jobs{ 1 };
  std::string   shard;
  bool          sharded{ false };  // --shard given (even empty)
  bool          targeted{ false }; // --bpv, --psnr or --points given
};

/** One thing to compress: a volume file, or one DICOM series of a directory. */
struct Item
{
  std::string path;     // the volume file, or the directory of the series
  std::string relative; // path in the tree ("." for the tree itself), '/' separated
  std::string series;   // Series Instance UID; empty for a volume file
  std::string name;     // of the output, without ".dcv"
  std::string refused;  // a reason to fail without reading anything (a name taken twice)
};

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

const char * const VolumeExtensions[] = { ".nrrd", ".nhdr", ".nii", ".nii.gz", ".mha", ".mhd" };

std::string
Lower(std::string s)
{
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

bool
EndsWith(const std::string & s, const std::string & end)
{
  return s.size() >= end.size() && s.compare(s.size() - end.size(), end.size(), end) == 0;
}

bool
IsVolumeFileName(const std::string & name)
{
  const std::string lower = Lower(name);
  return std::any_of(
    std::begin(VolumeExtensions), std::end(VolumeExtensions), [&](const char * e) { return EndsWith(lower, e); });
}

/** The data file of a .mhd or .nhdr header beside it (name.raw, name.zraw, name.raw.gz): part of that
 * volume, so not counted as skipped. */
bool
IsDataFileOfAHeader(const std::string & name, const std::set<std::string> & files)
{
  const std::string lower = Lower(name);
  for (const char * data : { ".raw", ".zraw", ".raw.gz" })
  {
    if (EndsWith(lower, data))
    {
      const std::string stem = name.substr(0, name.size() - std::string(data).size());
      return files.count(stem + ".mhd") || files.count(stem + ".nhdr");
    }
  }
  return false;
}

/** The Series Instance UID as FindDicomSeries reads it (from the series' first file), so that it finds
 * the series again; GDCM's grouping key when the header cannot be read (the item fails later, named). */
std::string
SeriesInstanceUID(const std::string & file, const std::string & fallback)
{
  auto io = itk::GDCMImageIO::New();
  io->SetFileName(file);
  try
  {
    io->ReadImageInformation();
  }
  catch (const itk::ExceptionObject &)
  {
    return fallback;
  }
  std::string uid;
  itk::ExposeMetaData<std::string>(io->GetMetaDataDictionary(), "0020|000e", uid);
  uid.erase(uid.find_last_not_of(std::string(" \t\r\n\0", 5)) + 1);
  uid.erase(0, std::min(uid.size(), uid.find_first_not_of(" \t\r\n")));
  return uid.empty() ? fallback : uid;
}

void
ListDirectory(const fs::path & tree, const fs::path & directory, const fs::path & outputDir, std::vector<Item> & items,
              std::size_t & skipped)
{
  std::error_code                  error;
  std::vector<fs::directory_entry> entries;
  for (fs::directory_iterator it(directory, error), end; !error && it != end; it.increment(error))
  {
    entries.push_back(*it);
  }
  if (error)
  {
    throw Failure("cannot list " + Quoted(directory.string()) + ": " + error.message());
  }
  // Sorted: the order of the items, hence the shards, must not depend on the file system.
  std::sort(entries.begin(), entries.end(), [](const auto & a, const auto & b) { return a.path() < b.path(); });
  std::string              relative = directory.lexically_relative(tree).generic_string();
  std::vector<std::string> volumes, others;
  std::set<std::string>    names;
  for (const auto & entry : entries)
  {
    const std::string name = entry.path().filename().string();
    // Symbolic links to directories are not followed: a loop would never end.
    if (entry.is_directory(error) && !entry.is_symlink(error))
    {
      if (!fs::equivalent(entry.path(), outputDir, error)) // the outputs of a run are not inputs of the next
      {
        ListDirectory(tree, entry.path(), outputDir, items, skipped);
      }
    }
    else if (entry.is_regular_file(error))
    {
      (IsVolumeFileName(name) ? volumes : others).push_back(name);
      names.insert(name);
    }
  }
  std::set<std::string> dicom;
  // GDCM's series scan is run only where a file is DICOM: it warns on a directory without any.
  auto       gdcm = itk::GDCMImageIO::New();
  const bool hasDicom = std::any_of(others.begin(), others.end(), [&](const std::string & name) {
    return gdcm->CanReadFile((directory / name).string().c_str());
  });
  if (hasDicom)
  {
    for (const auto & [uid, files] : ListDicomSeries(directory.string()))
    {
      if (files.empty())
      {
        continue;
      }
      for (const auto & f : files)
      {
        dicom.insert(fs::path(f).filename().string());
      }
      Item item;
      item.path = directory.string();
      item.relative = relative;
      item.series = SeriesInstanceUID(files.front(), uid);
      items.push_back(item);
    }
  }
  for (const auto & name : volumes)
  {
    Item item;
    item.path = (directory / name).string();
    item.relative = relative == "." ? name : relative + "/" + name;
    items.push_back(item);
  }
  for (const auto & name : others)
  {
    skipped += dicom.count(name) || IsDataFileOfAHeader(name, names) ? 0 : 1;
  }
}

/** Every item of the tree, sorted, named after its relative path with '/' replaced by '_' (plus
 * "_<Series Instance UID>" for a DICOM series); a name two items would share refuses both. */
std::vector<Item>
ListItems(const fs::path & tree, const fs::path & outputDir, std::size_t & skipped)
{
  std::vector<Item> items;
  ListDirectory(tree, tree, outputDir, items, skipped);
  std::sort(items.begin(), items.end(), [](const Item & a, const Item & b) {
    return std::tie(a.relative, a.series) < std::tie(b.relative, b.series);
  });
  std::map<std::string, std::size_t> taken;
  for (std::size_t i = 0; i < items.size(); ++i)
  {
    Item &      item = items[i];
    std::string flat = item.relative;
    std::replace(flat.begin(), flat.end(), '/', '_');
    item.name = item.series.empty() ? flat : (flat == "." ? item.series : flat + "_" + item.series);
    const auto [at, fresh] = taken.emplace(item.name, i);
    if (!fresh)
    {
      Item & first = items[at->second];
      item.refused = "its output name " + Quoted(item.name + ".dcv") + " is also that of " + Quoted(first.path);
      if (first.refused.empty())
      {
        first.refused = "its output name " + Quoted(item.name + ".dcv") + " is also that of " + Quoted(item.path);
      }
    }
  }
  return items;
}

/** K and N of --shard K/N; Failure with the expected form otherwise. */
std::pair<unsigned, unsigned>
ParseShard(const std::string & text)
{
  const auto slash = text.find('/');
  const auto digits = [](const std::string & s) {
    return !s.empty() && s.size() <= 9 &&
           std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
  };
  if (slash != std::string::npos && digits(text.substr(0, slash)) && digits(text.substr(slash + 1)))
  {
    const unsigned k = unsigned(std::stoul(text.substr(0, slash)));
    const unsigned n = unsigned(std::stoul(text.substr(slash + 1)));
    if (k >= 1 && k <= n)
    {
      return { k, n };
    }
  }
  throw Failure("--shard " + Quoted(text) + ": expected K/N with 1 <= K <= N (e.g. --shard 2/8: the second of 8)");
}

std::size_t
PixelSize(PixelType type)
{
  std::size_t size = 0;
  VisitPixelType(type, [&](auto pixel) { size = sizeof(pixel); });
  return size;
}

double
Ratio(const FileHeader & header, std::size_t bytes)
{
  return double(header.size.NumberOfVoxels()) * double(PixelSize(header.pixelType)) / double(bytes);
}

/** A reason on one line (the table and the CSV have one row per item), without the address of the
 * ITK object that threw (it would differ from run to run). */
std::string
OneLine(const std::string & reason)
{
  static const std::regex itkPrefix("ITK ERROR: [A-Za-z0-9_:]+\\(0x[0-9a-fA-F]+\\): ");
  std::istringstream      lines(std::regex_replace(reason, itkPrefix, ""));
  std::string             out, line;
  while (std::getline(lines, line))
  {
    const auto first = line.find_first_not_of(" \t\r");
    const auto last = line.find_last_not_of(" \t\r");
    if (first != std::string::npos)
    {
      out += (out.empty() ? "" : " ") + line.substr(first, last - first + 1);
    }
  }
  return out;
}

/** Reads (when valid and not `force`) or makes the item's .dcv file. Never throws: a failure is the
 * item's status. */
Outcome
CompressItem(const Item & item, const fs::path & outputDir, const EncoderOptions & base, bool force,
             const std::function<void(double)> & progress)
{
  const auto        start = std::chrono::steady_clock::now();
  const std::string output = (outputDir / (item.name + ".dcv")).string();
  Outcome           o;
  const auto        fail = [&](const std::string & reason) {
    o.reason = OneLine(reason);
    o.status = "failed: " + o.reason;
    o.seconds = SecondsSince(start);
    return o;
  };
  if (!item.refused.empty())
  {
    return fail(item.refused);
  }
  if (!force && fs::exists(output))
  {
    try
    {
      const CompressedFile file = ReadCompressedFile(output); // parsed and CRC-checked
      o.status = "skipped (exists)";
      o.failed = false;
      o.slices = file.header.size.z;
      o.bytes = file.size;
      o.ratio = Ratio(file.header, file.size);
      o.seconds = SecondsSince(start);
      return o;
    }
    catch (const FormatError &)
    {
      // Not a valid .dcv (damaged, or not ours): made again below.
    }
  }
  try
  {
    const VolumeInput volume = OpenVolume(item.path, item.series);
    EncoderOptions    options = base;
    options.metadata.insert(options.metadata.begin(), volume.metadata.begin(), volume.metadata.end());
    options.progress = progress;
    EncoderResult r;
    VisitPixelType(volume.type, [&](auto pixel) {
      const auto image = ReadVolume<decltype(pixel)>(volume);
      r = itk::DCVEncode(image.GetPointer(), options);
    });
    WriteFileAtomically(output, r.bytes);
    o.status = "ok";
    o.failed = false;
    o.slices = r.header.size.z;
    o.bytes = r.bytes.size();
    o.ratio = Ratio(r.header, r.bytes.size());
    o.psnr = r.psnr;
  }
  catch (const itk::ExceptionObject & e)
  {
    return fail(e.GetDescription());
  }
  catch (const std::exception & e)
  {
    return fail(e.what());
  }
  catch (...)
  {
    return fail("unknown error");
  }
  o.seconds = SecondsSince(start);
  return o;
}

std::string
Fixed(double v, int digits)
{
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

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

void
Batch(const BatchOptions & b)
{
  if (!b.targeted)
  {
    throw Failure("batch needs a target: --bpv R, --psnr DB or --points N");
  }
  MethodOptions method = b.method;
  method.quiet = true; // the encoder's own progress line would fight the batch's
  EncoderOptions                               base = method.Checked("");
  std::optional<std::pair<unsigned, unsigned>> shard;
  if (b.sharded)
  {
    shard = ParseShard(b.shard);
  }
  if (!fs::is_directory(b.tree))
  {
    throw Failure(Quoted(b.tree) +
                  (fs::exists(b.tree) ? " is not a directory (dcv compress takes one volume)" : ": no such directory"));
  }
  std::size_t skipped = 0;
  // "tree/", "./tree/." and "tree" name the same items, and the paths in messages read plainly.
  fs::path tree = fs::path(b.tree).lexically_normal();
  if (tree.filename().empty() && tree != tree.root_path())
  {
    tree = tree.parent_path();
  }
  std::vector<Item> items = ListItems(tree, fs::path(b.output), skipped);
  if (items.empty())
  {
    throw Failure("no DICOM series and no volume file (" + std::string(".nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd") +
                  ") in " + Quoted(tree.string()));
  }
  // Created once the tree is listed: a refused run leaves nothing behind.
  std::error_code error;
  fs::create_directories(b.output, error);
  if (!fs::is_directory(b.output))
  {
    throw Failure("cannot create the output directory " + Quoted(b.output) +
                  (error ? ": " + error.message() : std::string()));
  }
  const std::size_t all = items.size();
  if (shard)
  {
    std::vector<Item> kept;
    for (std::size_t i = 0; i < items.size(); ++i)
    {
      if (i % shard->second == shard->first - 1)
      {
        kept.push_back(items[i]);
      }
    }
    items.swap(kept);
  }
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  unsigned       jobs = b.jobs == 0 ? cores : b.jobs;
  jobs = unsigned(std::max<std::size_t>(1, std::min<std::size_t>(jobs, items.size())));
  if (base.threads == 0)
  {
    base.threads = std::max(1u, cores / jobs); // the cores shared among the jobs
  }
  // ITK's filters (the bilateral filter of I*) would otherwise start a thread per core in every job.
  itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(base.threads);
  // ITK's object factories are set up on first use; done here, before the workers race to it.
  itk::ObjectFactoryBase::GetRegisteredFactories();
  if (!b.method.quiet)
  {
    std::cerr << "batch: " << all << " item" << (all == 1 ? "" : "s") << " in " << Quoted(tree.string());
    if (shard)
    {
      std::cerr << ", shard " << shard->first << "/" << shard->second << ": " << items.size() << " of them";
    }
    std::cerr << ", " << jobs << " job" << (jobs == 1 ? "" : "s") << std::endl;
  }

  std::vector<Outcome>     outcomes(items.size());
  BatchProgress            progress(items.size(), jobs, b.method.quiet);
  std::atomic<std::size_t> next{ 0 };
  const fs::path           outputDir(b.output);
  const auto               work = [&](unsigned worker) {
    for (std::size_t i; (i = next++) < items.size();)
    {
      progress.Started(worker, items[i].name);
      outcomes[i] = CompressItem(
        items[i], outputDir, base, b.method.force, [&progress, worker](double f) { progress.Fraction(worker, f); });
      progress.Finished(worker, items[i].name, outcomes[i]);
    }
  };
  std::vector<std::thread> workers;
  for (unsigned w = 1; w < jobs; ++w)
  {
    workers.emplace_back(work, w);
  }
  work(0);
  for (auto & t : workers)
  {
    t.join();
  }
  progress.Done();

  const std::string csv = (outputDir / (shard ? "batch-summary-" + std::to_string(shard->first) + "-of-" +
                                                  std::to_string(shard->second) + ".csv"
                                              : std::string("batch-summary.csv")))
                            .string();
  WriteSummaryCsv(csv, items, outcomes);
  if (!b.method.quiet)
  {
    PrintSummaryTable(items, outcomes);
    if (skipped > 0)
    {
      std::cerr << "batch: skipped " << skipped << " file" << (skipped == 1 ? " that is" : "s that are")
                << " neither DICOM nor a volume file (.nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd)" << std::endl;
    }
  }
  std::ostringstream failed;
  std::size_t        failures = 0;
  for (std::size_t i = 0; i < items.size(); ++i)
  {
    if (outcomes[i].failed)
    {
      ++failures;
      failed << "\n  " << items[i].name << " (" << Quoted(items[i].path)
             << (items[i].series.empty() ? "" : ", series " + items[i].series) << "): " << outcomes[i].reason;
    }
  }
  if (failures > 0)
  {
    throw Failure("batch: " + std::to_string(failures) + " of " + std::to_string(items.size()) + " item" +
                  (items.size() == 1 ? "" : "s") + " failed:" + failed.str());
  }
}

const RegisterCommand batch{
  { "batch",
    "Compress every DICOM series and volume file of a tree into OUTPUT_DIR, one .dcv each; reruns "
    "skip valid outputs; prints a summary (also OUTPUT_DIR/batch-summary.csv)",
    [](CLI::App & command) -> std::function<void()> {
      auto b = std::make_shared<BatchOptions>();
      // The method's options as compress takes them; INPUT is a tree here, and --series has no use
      // (every series is compressed).
      AddMethodOptions(command, b->unused, b->method);
      command.remove_option(command.get_option("INPUT"));
      command.remove_option(command.get_option("--series"));
      command.get_option("--force")->description("Redo the items whose .dcv file exists and is valid");
      command.get_option("--quiet")->description("Print nothing but errors (the CSV summary is still written)");
      command
        .add_option("INPUT_TREE",
                    b->tree,
                    "Directory searched recursively: every DICOM series (per directory and Series Instance UID) and "
                    "every .nrrd, .nhdr, .nii, .nii.gz, .mha and .mhd file is an item")
        ->required();
      command
        .add_option("OUTPUT_DIR",
                    b->output,
                    "Directory of the .dcv files (created): the item's path in the tree with '/' as '_', plus "
                    "_<SeriesInstanceUID> for DICOM, then .dcv")
        ->required();
      const TargetOptions target = AddTargetOptions(command, b->method.encoder);
      command.add_option("--jobs,-j", b->jobs, "Items compressed at a time (0: one per core)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
      auto * shard =
        command.add_option("--shard", b->shard, "K/N: only the items whose index (in the sorted list) modulo N is K-1");
      return [b, target, shard] {
        b->targeted = target.bpv->count() + target.psnr->count() + target.points->count() > 0;
        b->sharded = shard->count() > 0;
        Batch(*b);
      };
    } }
};
} // namespace
} // namespace dcv::tools
