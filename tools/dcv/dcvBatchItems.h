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
#ifndef dcvBatchItems_h
#define dcvBatchItems_h

// What dcv batch compresses: the items of a tree (volume files and DICOM series), and its shards.
#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace dcv::tools
{

/** One thing to compress: a volume file, or one DICOM series of a directory. */
struct Item
{
  std::string path;     // the volume file, or the directory of the series
  std::string relative; // path in the tree ("." for the tree itself), '/' separated
  std::string series;   // Series Instance UID; empty for a volume file
  std::string name;     // of the output, without ".dcv"
  std::string refused;  // a reason to fail without reading anything (a name taken twice)
};

/** Every item of the tree, sorted, named after its relative path with '/' replaced by '_' (plus
 * "_<Series Instance UID>" for a DICOM series); a name two items would share refuses both. */
std::vector<Item>
ListItems(const std::filesystem::path & tree, const std::filesystem::path & outputDir, std::size_t & skipped);

/** K and N of --shard K/N; Failure with the expected form otherwise. */
std::pair<unsigned, unsigned>
ParseShard(const std::string & text);

} // namespace dcv::tools

#endif
