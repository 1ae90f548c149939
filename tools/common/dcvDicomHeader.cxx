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
#include "dcvDicomHeader.h"
#include "dcvTools.h"

#include <dcmtk/dcmdata/dcistrmb.h>
#include <dcmtk/dcmdata/dcistrmf.h>
#include <dcmtk/dcmdata/dcostrmb.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/oflog/oflog.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>

namespace fs = std::filesystem;

namespace dcv::tools
{
namespace
{
/** DCMTK's own messages off: every failure is reported here, naming the file. */
void
QuietDcmtk()
{
  static const bool once = [] {
    OFLog::configure(OFLogger::FATAL_LOG_LEVEL);
    return true;
  }();
  (void)once;
}

std::string
Count(uint64_t n)
{
  return std::to_string(n);
}

/** Where the pixel data element is: its tag found, its header whole, its value's length and start. */
struct PixelDataAt
{
  bool     found{ false };
  bool     complete{ false };
  uint32_t length{ 0 };
  uint64_t start{ 0 };
};

/** The pixel data element's header, which DCMTK's reader stopped at or just after (`stop`): its value's
 * length and where the value starts, found in the file's bytes around that point. */
PixelDataAt
FindPixelData(const std::string & file, uint64_t stop, bool big)
{
  const uint64_t from = stop > 16 ? stop - 16 : 0;
  std::string    window(32, '\0');
  {
    std::ifstream raw(file, std::ios::binary);
    raw.seekg(std::streamoff(from));
    raw.read(&window[0], std::streamsize(window.size()));
    window.resize(std::size_t(raw.gcount()));
  }
  const std::string tag = big ? std::string("\x7f\xe0\x00\x10", 4) : std::string("\xe0\x7f\x10\x00", 4);
  const auto        u32 = [&](std::size_t at) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i)
      v |= uint32_t(uint8_t(window[at + (big ? 3 - i : i)])) << (8 * i);
    return v;
  };
  PixelDataAt       p;
  const std::size_t at = window.find(tag);
  if (at == std::string::npos)
  {
    return p;
  }
  p.found = true;
  // Explicit VR when a VR of pixel data follows the tag with its two reserved bytes (the transfer syntax
  // the reader found may be unknown here).
  const std::string vr = at + 8 <= window.size() ? window.substr(at + 4, 4) : std::string();
  const bool        explicitVr = vr.size() == 4 && vr[2] == '\0' && vr[3] == '\0' &&
                          std::string("OB OW OF OD OL OV UN").find(vr.substr(0, 2)) != std::string::npos;
  const std::size_t valueAt = explicitVr ? at + 12 : at + 8;
  if (valueAt > window.size())
  {
    return p;
  }
  p.complete = true;
  p.length = explicitVr ? u32(at + 8) : u32(at + 4);
  p.start = from + valueAt;
  return p;
}

/** Reads the header of `file` (every element before its pixel data) into `f` and checks the pixel data
 * (CheckDicomPixelData). */
void
LoadHeader(const std::string & file, DcmFileFormat & f)
{
  QuietDcmtk();
  const std::string what = "cannot read the DICOM file " + Quoted(file);
  std::error_code   error;
  const uint64_t    size = fs::file_size(file, error);
  if (error)
  {
    throw Failure(what + ": " + error.message());
  }
  DcmInputFileStream in(file.c_str());
  if (in.status().bad())
  {
    throw Failure(what + ": " + in.status().text());
  }
  f.transferInit();
  const OFCondition c = f.readUntilTag(in, EXS_Unknown, EGL_noChange, DCM_MaxReadLength, DCM_PixelData);
  f.transferEnd();
  if (c.bad())
  {
    throw Failure(what + ": its header is damaged or cut short (" + c.text() + ")");
  }
  DcmDataset &      ds = *f.getDataset();
  const PixelDataAt at = FindPixelData(file, uint64_t(in.tell()), DcmXfer(ds.getOriginalXfer()).isBigEndian());
  if (!at.found)
  {
    throw Failure(what + ": it has no pixel data (the file ends after its header, at byte " + Count(size) + ")");
  }
  if (!at.complete)
  {
    throw Failure(what + ": it is cut short in the header of its pixel data (the file ends at byte " + Count(size) +
                  ")");
  }
  const uint32_t length = at.length;
  const uint64_t start = at.start;
  if (length == 0xffffffffu)
  {
    // Encapsulated (compressed) pixel data: its fragments read whole, or not.
    DcmFileFormat whole;
    OFCondition   loaded = whole.loadFile(file.c_str());
    DcmElement *  pixels = nullptr;
    if (loaded.good() && whole.getDataset()->findAndGetElement(DCM_PixelData, pixels).good() && pixels)
      loaded = pixels->loadAllDataIntoMemory();
    if (loaded.bad())
    {
      throw Failure(what + ": its compressed pixel data is cut short or damaged (" + loaded.text() + ")");
    }
    return;
  }
  const uint64_t present = size > start ? size - start : 0;
  if (present < length)
  {
    throw Failure(what + ": it is cut short: its pixel data is " + Count(length) +
                  " bytes by its header, the file ends after " + Count(present) + " of them (" +
                  Count(length - present) + " bytes missing, the file has " + Count(size) + " bytes)");
  }
  Uint16 rows = 0, columns = 0, samples = 1, bits = 0;
  ds.findAndGetUint16(DCM_Rows, rows);
  ds.findAndGetUint16(DCM_Columns, columns);
  ds.findAndGetUint16(DCM_SamplesPerPixel, samples);
  ds.findAndGetUint16(DCM_BitsAllocated, bits);
  Sint32 frames = 1;
  if (ds.findAndGetSint32(DCM_NumberOfFrames, frames).bad() || frames < 1)
    frames = 1;
  const uint64_t needed = (uint64_t(rows) * columns * std::max<Uint16>(samples, 1) * bits * uint64_t(frames) + 7) / 8;
  if (length < needed)
  {
    throw Failure(what + ": its pixel data is " + Count(length) +
                  " bytes; its rows, columns, samples, bits and frames (" + Count(columns) + " x " + Count(rows) +
                  " x " + Count(samples) + " x " + Count(bits) + " bits x " + Count(uint64_t(frames)) + ") need " +
                  Count(needed) + " (" + Count(needed - length) + " bytes missing)");
  }
}

/** Attributes a .dcv file never stores: the pixel data (its own), group lengths, padding. */
bool
Excluded(const DcmTagKey & t)
{
  return t.getElement() == 0x0000 || t.getGroup() == 0x0002 || t.getGroup() == 0x7fe0 ||
         t == DCM_DataSetTrailingPadding;
}

/** The attributes of the essential header: patient, study, series, equipment, frame of reference, image
 * plane and pixel modules, Specific Character Set, VOI LUT, per-slice position and instance data. */
bool
Essential(const DcmTagKey & t)
{
  const Uint16 g = t.getGroup();
  if (g & 1)
  {
    return false; // private
  }
  if (g == 0x0010 || g == 0x0028)
  {
    return true; // patient; image pixel, image plane spacing, VOI LUT, rescale
  }
  static const DcmTagKey kept[] = {
    DCM_SpecificCharacterSet,
    DCM_ImageType,
    DCM_InstanceCreationDate,
    DCM_InstanceCreationTime,
    DCM_SOPClassUID,
    DCM_SOPInstanceUID,
    DCM_StudyDate,
    DCM_SeriesDate,
    DCM_AcquisitionDate,
    DCM_ContentDate,
    DCM_StudyTime,
    DCM_SeriesTime,
    DCM_AcquisitionTime,
    DCM_ContentTime,
    DCM_AccessionNumber,
    DCM_Modality,
    DCM_Manufacturer,
    DCM_InstitutionName,
    DCM_InstitutionAddress,
    DCM_ReferringPhysicianName,
    DCM_StationName,
    DCM_StudyDescription,
    DCM_SeriesDescription,
    DCM_InstitutionalDepartmentName,
    DCM_PerformingPhysicianName,
    DCM_OperatorsName,
    DCM_ManufacturerModelName,
    DCM_BodyPartExamined,
    DCM_SliceThickness,
    DCM_KVP,
    DCM_SpacingBetweenSlices,
    DCM_DeviceSerialNumber,
    DCM_SoftwareVersions,
    DCM_ProtocolName,
    DCM_PatientPosition,
    DCM_StudyInstanceUID,
    DCM_SeriesInstanceUID,
    DCM_StudyID,
    DCM_SeriesNumber,
    DCM_AcquisitionNumber,
    DCM_InstanceNumber,
    DCM_PatientOrientation,
    DCM_ImagePositionPatient,
    DCM_ImageOrientationPatient,
    DCM_FrameOfReferenceUID,
    DCM_Laterality,
    DCM_PositionReferenceIndicator,
    DCM_SliceLocation,
  };
  return std::find(std::begin(kept), std::end(kept), t) != std::end(kept);
}

/** One data element as DICOM explicit VR little endian bytes, lengths explicit. */
std::string
Encode(DcmObject & element, const std::string & file)
{
  std::string           out;
  std::vector<Uint8>    buffer(1 << 16);
  DcmOutputBufferStream stream(buffer.data(), offile_off_t(buffer.size()));
  void *                data = nullptr;
  offile_off_t          n = 0;
  element.transferInit();
  OFCondition c;
  while ((c = element.write(stream, EXS_LittleEndianExplicit, EET_ExplicitLength, nullptr)) == EC_StreamNotifyClient)
  {
    stream.flushBuffer(data, n);
    out.append(static_cast<const char *>(data), std::size_t(n));
  }
  element.transferEnd();
  if (c.bad())
  {
    throw Failure("cannot store the attribute " + std::string(element.getTag().toString().c_str()) + " of " +
                  Quoted(file) + ": " + c.text());
  }
  stream.flush();
  stream.flushBuffer(data, n);
  out.append(static_cast<const char *>(data), std::size_t(n));
  return out;
}

/** Reads the elements of one part of a header block into `into` (replacing any of the same tag). */
void
ReadPart(const std::string & part, DcmDataset & into, const std::string & name)
{
  if (part.empty())
  {
    return;
  }
  DcmInputBufferStream in;
  in.setBuffer(part.data(), offile_off_t(part.size()));
  in.setEos();
  DcmDataset d;
  d.transferInit();
  const OFCondition c = d.read(in, EXS_LittleEndianExplicit, EGL_noChange, DCM_MaxReadLength);
  d.transferEnd();
  if (c.bad() || !in.eos())
  {
    throw Failure(name + ": damaged DICOM header block (" + (c.bad() ? c.text() : "bytes left over") + ")");
  }
  while (d.card() > 0)
  {
    DcmElement * e = d.remove(0UL);
    if (into.insert(e, OFTrue).bad())
    {
      delete e;
      throw Failure(name + ": damaged DICOM header block");
    }
  }
}
} // namespace

const char *
DicomHeaderModeName(DicomHeaderMode mode)
{
  return mode == DicomHeaderMode::Full ? "full" : "essential";
}

void
CheckDicomPixelData(const std::string & file)
{
  DcmFileFormat f;
  LoadHeader(file, f);
}

bool
StartsAsDicom(const std::string & file)
{
  std::ifstream raw(file, std::ios::binary);
  char          head[132] = {};
  raw.read(head, sizeof head);
  const std::size_t n = std::size_t(raw.gcount());
  if (n == sizeof head && std::string(head + 128, 4) == "DICM")
  {
    return true; // preamble and prefix (DICOM PS3.10)
  }
  if (n < 8)
  {
    return false;
  }
  // A data set without preamble: its first tag in group 0002 or 0008, little or big endian, followed by
  // an explicit VR (two capital letters) or an implicit length shorter than the file.
  const auto u16 = [&](int at, bool big) {
    return uint16_t(big ? (uint8_t(head[at]) << 8) | uint8_t(head[at + 1])
                        : uint8_t(head[at]) | (uint8_t(head[at + 1]) << 8));
  };
  const bool explicitVr = std::isupper(uint8_t(head[4])) && std::isupper(uint8_t(head[5]));
  for (const bool big : { false, true })
  {
    const uint16_t group = u16(0, big);
    if (group != 0x0002 && group != 0x0008)
      continue;
    uint32_t length = 0;
    for (int i = 0; i < 4; ++i)
      length |= uint32_t(uint8_t(head[4 + (big ? 3 - i : i)])) << (8 * i);
    std::error_code error;
    if (explicitVr || length < fs::file_size(file, error))
      return true;
  }
  return false;
}

std::vector<DicomFileHeader>
CheckDicomHeaders(const std::string & directory)
{
  QuietDcmtk();
  std::vector<std::string> files;
  std::error_code          error;
  for (fs::directory_iterator it(directory, error), end; !error && it != end; it.increment(error))
  {
    if (it->is_regular_file(error))
      files.push_back(it->path().string());
  }
  std::sort(files.begin(), files.end());
  std::vector<DicomFileHeader> headers;
  for (const auto & file : files)
  {
    if (!StartsAsDicom(file))
      continue;
    const std::string  what = "cannot read the DICOM file " + Quoted(file);
    const uint64_t     size = fs::file_size(file, error);
    DcmFileFormat      f;
    DcmInputFileStream in(file.c_str());
    if (error || in.status().bad())
      continue; // unreadable: GDCM skips it too
    f.transferInit();
    const OFCondition c = f.readUntilTag(in, EXS_Unknown, EGL_noChange, DCM_MaxReadLength, DCM_PixelData);
    f.transferEnd();
    DcmDataset &      ds = *f.getDataset();
    const std::string cut = ": it is cut short inside its header (the file ends at byte " + Count(size) + ")";
    if (c.bad() && (in.eos() || c == EC_StreamNotifyClient))
    {
      throw Failure(what + cut);
    }
    if (c.bad())
    {
      continue; // damaged otherwise: left to GDCM, as before
    }
    if (ds.card() == 0)
    {
      throw Failure(what + cut); // the file meta information and nothing after it
    }
    DicomFileHeader h;
    h.file = file;
    const PixelDataAt at = FindPixelData(file, uint64_t(in.tell()), DcmXfer(ds.getOriginalXfer()).isBigEndian());
    if (at.found && !at.complete)
    {
      throw Failure(what + cut);
    }
    h.pixelData = at.found;
    OFString sopClass, series;
    Uint16   rows = 0, columns = 0;
    ds.findAndGetOFString(DCM_SOPClassUID, sopClass);
    ds.findAndGetOFString(DCM_SeriesInstanceUID, series);
    ds.findAndGetUint16(DCM_Rows, rows);
    ds.findAndGetUint16(DCM_Columns, columns);
    h.seriesUid = series.c_str();
    const bool imageClass = std::any_of(dcmImageSOPClassUIDs,
                                        dcmImageSOPClassUIDs + numberOfDcmImageSOPClassUIDs,
                                        [&](const char * uid) { return uid && sopClass == uid; });
    h.image = imageClass && rows > 0 && columns > 0;
    headers.push_back(std::move(h));
  }
  return headers;
}

std::string
ReadDicomHeaders(const std::vector<std::string> & files, DicomHeaderMode mode)
{
  std::vector<std::map<uint32_t, std::string>> elements(files.size());
  for (std::size_t i = 0; i < files.size(); ++i)
  {
    DcmFileFormat f;
    LoadHeader(files[i], f);
    DcmDataset & ds = *f.getDataset();
    for (unsigned long k = 0; k < ds.card(); ++k)
    {
      DcmElement *    e = ds.getElement(k);
      const DcmTagKey t = e->getTag();
      if (Excluded(t) || (mode == DicomHeaderMode::Essential && !Essential(t)))
        continue;
      elements[i][(uint32_t(t.getGroup()) << 16) | t.getElement()] = Encode(*e, files[i]);
    }
  }
  DicomHeaderBlock block;
  block.mode = mode == DicomHeaderMode::Full ? 0 : 1;
  block.files.resize(files.size());
  std::vector<uint32_t> common;
  for (const auto & [tag, bytes] : elements.front())
  {
    if (std::all_of(elements.begin() + 1, elements.end(), [&, t = tag, &b = bytes](const auto & m) {
          const auto it = m.find(t);
          return it != m.end() && it->second == b;
        }))
    {
      block.common += bytes;
      common.push_back(tag);
    }
  }
  for (auto & m : elements)
  {
    for (const uint32_t tag : common)
      m.erase(tag);
  }
  for (std::size_t i = 0; i < files.size(); ++i)
  {
    for (const auto & [tag, bytes] : elements[i])
      block.files[i] += bytes;
  }
  return JoinDicomHeader(block);
}

std::size_t
DicomHeaderBytes(const FileHeader & header)
{
  FileHeader without = header;
  without.metadata.clear();
  bool found = false;
  for (const auto & kv : header.metadata)
  {
    if (kv.first == DicomHeaderKey)
      found = true;
    else
      without.metadata.push_back(kv);
  }
  if (!found)
  {
    return 0;
  }
  return SerializeFile(header, {}).size() - SerializeFile(without, {}).size();
}

StoredDicomHeaders::StoredDicomHeaders() = default;
StoredDicomHeaders::~StoredDicomHeaders() = default;
StoredDicomHeaders::StoredDicomHeaders(StoredDicomHeaders &&) noexcept = default;
StoredDicomHeaders &
StoredDicomHeaders::operator=(StoredDicomHeaders &&) noexcept = default;

StoredDicomHeaders
ParseDicomHeaders(const FileHeader & header, const std::string & name)
{
  QuietDcmtk();
  StoredDicomHeaders stored;
  for (const auto & kv : header.metadata)
  {
    if (kv.first != DicomHeaderKey)
      continue;
    const DicomHeaderBlock block = SplitDicomHeader(kv.second, name);
    stored.mode = block.mode == 0 ? DicomHeaderMode::Full : DicomHeaderMode::Essential;
    for (const auto & own : block.files)
    {
      auto ds = std::make_unique<DcmDataset>();
      ReadPart(block.common, *ds, name);
      ReadPart(own, *ds, name);
      stored.files.push_back(std::move(ds));
    }
  }
  return stored;
}

} // namespace dcv::tools
