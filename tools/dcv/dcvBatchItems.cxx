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
#include "dcvBatchItems.h"
#include "dcvCommand.h"
#include "itkMetaDataObject.h"

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <tuple>

namespace fs = std::filesystem;

namespace dcv::tools
{
namespace
{
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
  auto io = GDCM().newImageIO();
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
  std::string           cut;
  if (!others.empty())
  {
    try
    {
      CheckDicomHeaders(directory.string());
    }
    catch (const Failure & e)
    {
      cut = e.what();
    }
  }
  if (!cut.empty())
  {
    // GDCM's scan would abort on that file, so the directory's series are not listed: it fails as one item,
    // the others go on.
    Item item;
    item.path = directory.string();
    item.relative = relative;
    item.refused = cut;
    items.push_back(item);
    for (const auto & name : others)
    {
      if (StartsAsDicom((directory / name).string()))
        dicom.insert(name);
    }
  }
  // GDCM's series scan is run only where a file is DICOM: it warns on a directory without any.
  const bool hasDicom = cut.empty() && !others.empty() && [&] {
    const auto gdcm = GDCM().newImageIO();
    return std::any_of(others.begin(), others.end(), [&](const std::string & name) {
      return gdcm->CanReadFile((directory / name).string().c_str());
    });
  }();
  if (hasDicom)
  {
    for (const auto & [uid, files] : ListCheckedDicomSeries(directory.string()))
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
} // namespace

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
    if (flat == "." && item.series.empty())
    {
      flat = tree.filename().string(); // the tree's own DICOM files, not listed (a file cut short)
    }
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
  throw UsageError("--shard " + Quoted(text) + ": expected K/N with 1 <= K <= N (e.g. --shard 2/8: the second of 8)");
}

} // namespace dcv::tools
