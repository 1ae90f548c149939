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
// The items of the tree are listed in dcvBatchItems.cxx, the summary and progress are in dcvBatchReport.cxx.
#include "dcvBatchItems.h"
#include "dcvBatchReport.h"
#include "dcvCommand.h"
#include "itkDCVEncoder.h"
#include "itkMultiThreaderBase.h"
#include "itkObjectFactoryBase.h"

#include <algorithm>
#include <atomic>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>

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
CompressItem(const Item & item, const fs::path & outputDir, const EncoderOptions & base, bool force, bool resample,
             DicomHeaderMode header, const std::function<void(double)> & progress)
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
    const VolumeInput volume = OpenVolume(item.path, item.series, resample, header);
    EncoderOptions    options = base;
    options.metadata.insert(options.metadata.begin(), volume.metadata.begin(), volume.metadata.end());
    options.progress = progress;
    EncoderResult r;
    VisitPixelType(volume.type, [&](auto pixel) {
      auto image = ReadVolume<decltype(pixel)>(volume);
      CheckFiniteVoxels(image.GetPointer(), item.path);
      CheckDicomHeaderFits(item.path, volume, options, header, image->GetBufferedRegion().GetNumberOfPixels());
      r = itk::DCVEncode(std::move(image), options); // freed once copied
    });
    // Replacing is allowed: an existing file here is damaged (a valid one was skipped) or --force.
    WriteOutputBytes(output, r.bytes, true);
    o.status = volume.resampling.needed ? "ok (resampled: " + volume.resampling.description + ")" : "ok";
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

void
Batch(const BatchOptions & b)
{
  if (!b.targeted)
  {
    throw UsageError("batch needs a target: --bpv R, --psnr DB or --points N");
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
      outcomes[i] = CompressItem(items[i],
                                 outputDir,
                                 base,
                                 b.method.force,
                                 b.method.resample,
                                 b.method.dicomHeader,
                                 [&progress, worker](double f) { progress.Fraction(worker, f); });
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
        b->targeted =
          target.bpv->count() + target.psnr->count() + target.points->count() + target.maximumError->count() > 0;
        b->sharded = shard->count() > 0;
        Batch(*b);
      };
    } }
};
} // namespace
} // namespace dcv::tools
