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
#ifndef dcvDicomHeader_h
#define dcvDicomHeader_h

// The DICOM header of every file of a series (DCMTK): read and checked (each file's pixel data whole),
// stored in a .dcv file as its "DICOM Header" metadata value (docs/format.md), and given back file by
// file to the DICOM writer.
#include "dcvFileFormat.h"

#include <memory>
#include <string>
#include <vector>

class DcmDataset;

namespace dcv::tools
{

/** What of each file's header a .dcv file keeps: every attribute, or what a valid, correctly displayed
 * derived series needs (docs/format.md, "DICOM header"). */
enum class DicomHeaderMode
{
  Full,
  Essential
};

/** "full" or "essential". */
const char *
DicomHeaderModeName(DicomHeaderMode mode);

/** Refuses (Failure naming the file and what is missing) a DICOM file whose header cannot be read, that
 * has no pixel data, or whose pixel data is cut short (the file ends before the bytes its header
 * announces, or they are fewer than its rows, columns, samples, bits and frames need). */
void
CheckDicomPixelData(const std::string & file);

/** What a file of a directory that starts as DICOM says of itself (CheckDicomHeaders). */
struct DicomFileHeader
{
  std::string file;
  std::string seriesUid;          // Series Instance UID
  bool        image{ false };     // image storage: an image SOP Class, Rows and Columns
  bool        pixelData{ false }; // a Pixel Data element after the header
};

/** Whether `file` starts as DICOM: a preamble and "DICM", or a data set whose first tag is of group 0002
 * or 0008. */
bool
StartsAsDicom(const std::string & file);

/** The headers (up to the pixel data, which is not read) of the files of `directory` (not of its
 * subdirectories) that start as DICOM, sorted by name. Refuses (Failure naming the file) one cut short
 * inside its header (or in the header of its pixel data): GDCM's series scan aborts the program on such
 * a file, so this runs before it. Files that do not start as DICOM, or whose header DCMTK cannot read
 * for another reason, are left out. */
std::vector<DicomFileHeader>
CheckDicomHeaders(const std::string & directory);

/** The header of every file of `files` (in that order: the volume's slices), pixel data excluded, as the
 * value of the "DICOM Header" metadata pair (docs/format.md): what is equal in all files once, the rest
 * per file. Each file's pixel data is checked first (CheckDicomPixelData). */
std::string
ReadDicomHeaders(const std::vector<std::string> & files, DicomHeaderMode mode);

/** The bytes the "DICOM Header" pair of `header` adds to its file (0 without one): the file with and
 * without it, the metadata deflated as the writer deflates it. */
std::size_t
DicomHeaderBytes(const FileHeader & header);

/** The header block of a .dcv file, parsed: one dataset per stored file (common and own attributes). */
struct StoredDicomHeaders
{
  DicomHeaderMode                          mode{ DicomHeaderMode::Full };
  std::vector<std::unique_ptr<DcmDataset>> files;
  StoredDicomHeaders();
  ~StoredDicomHeaders();
  StoredDicomHeaders(StoredDicomHeaders &&) noexcept;
  StoredDicomHeaders &
  operator=(StoredDicomHeaders &&) noexcept;
};

/** The stored headers of `header` (none: no "DICOM Header" pair); Failure naming `name` when DCMTK cannot
 * read one (the container's structure was checked when the file was parsed). */
StoredDicomHeaders
ParseDicomHeaders(const FileHeader & header, const std::string & name);

} // namespace dcv::tools

#endif
