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
#include "dcvDicomWriter.h"
#include "dcvBoundedLayer.h"
#include "dcvDicomHeader.h"
#include "dcvTools.h"
#include "dcvVersion.h"

#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <ctime>
#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>

namespace fs = std::filesystem;

namespace dcv::tools
{
namespace
{
std::string
NewUid()
{
  char uid[100];
  dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT);
  return uid;
}

std::string
Decimal(double v)
{
  // DICOM decimal strings hold at most 16 characters.
  std::ostringstream s;
  s.precision(10);
  s << v;
  std::string text = s.str();
  for (int precision = 9; text.size() > 16 && precision > 1; --precision)
  {
    std::ostringstream shorter;
    shorter.precision(precision);
    shorter << v;
    text = shorter.str();
  }
  return text;
}

/** How decoded values become stored pixels: value = slope * stored + intercept, stored in 16 bits. */
struct PixelEncoding
{
  double   slope{ 1.0 };
  double   intercept{ 0.0 };
  bool     isSigned{ false };
  unsigned bitsStored{ 16 };
};

double
StoredMin(const PixelEncoding & e)
{
  return e.isSigned ? -std::ldexp(1.0, int(e.bitsStored) - 1) : 0.0;
}

double
StoredMax(const PixelEncoding & e)
{
  return e.isSigned ? std::ldexp(1.0, int(e.bitsStored) - 1) - 1.0 : std::ldexp(1.0, int(e.bitsStored)) - 1.0;
}

/** Moves the rescale intercept by whole slopes (and adds bits, up to 16, only when the range is wider
 * than the original's bits hold) so that every decoded value in [lo, hi] is stored as it is: the spline
 * and the residual layer may undershoot the original's stored range (below -1024 HU for 12-bit CT), and
 * clamping those values would make the series differ from the decoded volume, and from the PSNR that
 * compress printed. */
void
KeepDecodedRange(PixelEncoding & e, double lo, double hi)
{
  if (!(lo <= hi) || !(e.slope > 0.0))
  {
    return;
  }
  const double first = std::round((lo - e.intercept) / e.slope);
  const double last = std::round((hi - e.intercept) / e.slope);
  if (first >= StoredMin(e) && last <= StoredMax(e))
  {
    return;
  }
  while (e.bitsStored < 16 && last - first > StoredMax(e) - StoredMin(e))
  {
    ++e.bitsStored;
  }
  if (first < StoredMin(e))
  {
    e.intercept -= e.slope * (StoredMin(e) - first);
  }
  else if (last > StoredMax(e))
  {
    e.intercept += e.slope * std::min(last - StoredMax(e), first - StoredMin(e));
  }
}

void
Put(DcmItem & d, const DcmTagKey & key, const std::string & value)
{
  const OFCondition c = d.putAndInsertString(key, value.c_str());
  if (c.bad())
  {
    throw Failure(std::string("cannot set a DICOM attribute: ") + c.text());
  }
}

std::string
Get(DcmItem & d, const DcmTagKey & key)
{
  OFString value;
  if (d.findAndGetOFStringArray(key, value).bad())
    return "";
  return value.c_str();
}

std::vector<std::string>
Values(const std::string & text)
{
  std::vector<std::string> values;
  std::stringstream        in(text);
  for (std::string v; std::getline(in, v, '\\');)
    values.push_back(v);
  return values;
}

std::string
Joined(const std::vector<std::string> & values)
{
  std::string text;
  for (std::size_t i = 0; i < values.size(); ++i)
    text += (i ? "\\" : "") + values[i];
  return text;
}

/** Replaces the sequence `tag` by one with a single item of a code (CodeValue, scheme, meaning), in `item`
 * when given. */
DcmItem *
PutCodeItem(DcmItem & d, const DcmTagKey & sequence, const char * value, const char * scheme, const char * meaning)
{
  d.findAndDeleteElement(sequence);
  DcmItem * item = nullptr;
  if (d.findOrCreateSequenceItem(sequence, item, -2).bad() || item == nullptr)
  {
    throw Failure("cannot set a DICOM sequence");
  }
  Put(*item, DCM_CodeValue, value);
  Put(*item, DCM_CodingSchemeDesignator, scheme);
  Put(*item, DCM_CodeMeaning, meaning);
  return item;
}

/** `text` and `suffix` within `limit` bytes: the text shortened (at a character boundary of UTF-8, and
 * never inside ISO 2022 escapes: such a text keeps its bytes and loses the suffix). */
std::string
WithSuffix(const std::string & text, const std::string & suffix, std::size_t limit, bool utf8)
{
  if (text.size() + suffix.size() <= limit)
    return text + suffix;
  if (text.find('\x1b') != std::string::npos)
    return text;
  std::size_t keep = limit > suffix.size() ? limit - suffix.size() : 0;
  while (utf8 && keep > 0 && keep < text.size() && (uint8_t(text[keep]) & 0xc0) == 0x80)
    --keep;
  return text.substr(0, keep) + suffix;
}

/** The changes that make an original file's header that of its lossy derived copy (docs/dicom.md):
 * new SOP Instance and Series Instance UIDs, Image Type DERIVED\\SECONDARY, lossy compression, derivation
 * and its codes, the source image, instance creation, series number and description, software
 * versions, the pixel module as stored. Everything else stays as the original has it, byte for byte. */
/** The type 2 attributes (and the conditional ones the series' own writer path sets) an original lacks,
 * empty: a derived series is valid even where its original was not. Present ones are kept as they are. */
void
CompleteType2(DcmDataset & ds, int32_t z)
{
  const auto absent = [&ds](const DcmTagKey & key) { return !ds.tagExists(key); };
  for (const DcmTagKey & key : { DCM_PatientName,
                                 DCM_PatientID,
                                 DCM_PatientBirthDate,
                                 DCM_PatientSex,
                                 DCM_StudyDate,
                                 DCM_StudyTime,
                                 DCM_ReferringPhysicianName,
                                 DCM_StudyID,
                                 DCM_AccessionNumber,
                                 DCM_PositionReferenceIndicator,
                                 DCM_Manufacturer })
  {
    if (absent(key))
      Put(ds, key, "");
  }
  if (absent(DCM_InstanceNumber))
    Put(ds, DCM_InstanceNumber, std::to_string(z + 1));
  const std::string sopClass = Get(ds, DCM_SOPClassUID);
  const bool        ct = sopClass == UID_CTImageStorage;
  if (absent(DCM_Laterality) && (!ct || absent(DCM_BodyPartExamined)))
    Put(ds, DCM_Laterality, ""); // type 2C: a paired body part (or one not known) needs it
  if (ct)
  {
    for (const DcmTagKey & key : { DCM_KVP, DCM_AcquisitionNumber, DCM_PatientPosition })
    {
      if (absent(key))
        Put(ds, key, "");
    }
  }
  if (sopClass == UID_SecondaryCaptureImageStorage)
  {
    if (absent(DCM_ConversionType))
      Put(ds, DCM_ConversionType, "WSD");
    if (absent(DCM_PatientOrientation))
      Put(ds, DCM_PatientOrientation, "");
  }
}

/** The image pixel module of a decoded slice: 16 bits allocated, the encoding the decoded range needs. */
void
PutPixelModule(DcmDataset & ds, const PixelEncoding & enc, int32_t columns, int32_t rows)
{
  Put(ds, DCM_SamplesPerPixel, "1");
  Put(ds, DCM_PhotometricInterpretation, "MONOCHROME2");
  Put(ds, DCM_Rows, std::to_string(rows));
  Put(ds, DCM_Columns, std::to_string(columns));
  Put(ds, DCM_BitsAllocated, "16");
  Put(ds, DCM_BitsStored, std::to_string(enc.bitsStored));
  Put(ds, DCM_HighBit, std::to_string(enc.bitsStored - 1));
  Put(ds, DCM_PixelRepresentation, enc.isSigned ? "1" : "0");
  Put(ds, DCM_RescaleIntercept, Decimal(enc.intercept));
  Put(ds, DCM_RescaleSlope, Decimal(enc.slope));
}

void
Derive(DcmDataset & ds, const std::string & series, const std::string & now, const std::string & derivation,
       double ratio, bool lossy, const PixelEncoding & enc, int32_t columns, int32_t rows, const std::string & software)
{
  const std::string sopClass = Get(ds, DCM_SOPClassUID);
  const std::string sopInstance = Get(ds, DCM_SOPInstanceUID);
  Put(ds, DCM_SOPInstanceUID, NewUid());
  Put(ds, DCM_SeriesInstanceUID, series);
  auto type = Values(Get(ds, DCM_ImageType));
  type.resize(std::max<std::size_t>(type.size(), 2));
  type[0] = "DERIVED";
  type[1] = "SECONDARY";
  Put(ds, DCM_ImageType, Joined(type));
  // An earlier lossy compression keeps its values; this one adds its own (PS3.3 C.7.6.1.1.5). A lossless
  // file adds nothing: the pixels are the original's, lossy only where the original already was.
  std::string ratioText = Decimal(ratio), method = "DCV";
  if (!lossy)
  {
    if (Get(ds, DCM_LossyImageCompression).empty())
      Put(ds, DCM_LossyImageCompression, "00");
  }
  else if (Get(ds, DCM_LossyImageCompression) == "01")
  {
    const std::string earlierRatio = Get(ds, DCM_LossyImageCompressionRatio);
    const std::string earlierMethod = Get(ds, DCM_LossyImageCompressionMethod);
    if (!earlierRatio.empty() && !earlierMethod.empty())
    {
      ratioText = earlierRatio + "\\" + ratioText;
      method = earlierMethod + "\\" + method;
    }
  }
  if (lossy)
  {
    Put(ds, DCM_LossyImageCompression, "01");
    Put(ds, DCM_LossyImageCompressionRatio, ratioText);
    Put(ds, DCM_LossyImageCompressionMethod, method);
  }
  Put(ds, DCM_DerivationDescription, derivation);
  if (lossy)
    PutCodeItem(ds, DCM_DerivationCodeSequence, "113040", "DCM", "Lossy Compression");
  ds.findAndDeleteElement(DCM_SourceImageSequence);
  DcmItem * source = nullptr;
  if (ds.findOrCreateSequenceItem(DCM_SourceImageSequence, source, -2).bad() || source == nullptr)
  {
    throw Failure("cannot set a DICOM sequence");
  }
  Put(*source, DCM_ReferencedSOPClassUID, sopClass);
  Put(*source, DCM_ReferencedSOPInstanceUID, sopInstance);
  if (lossy)
    PutCodeItem(*source, DCM_PurposeOfReferenceCodeSequence, "121320", "DCM", "Uncompressed predecessor");
  else
    PutCodeItem(
      *source, DCM_PurposeOfReferenceCodeSequence, "121322", "DCM", "Source image for image processing operation");
  Put(ds, DCM_InstanceCreationDate, now.substr(0, 8));
  Put(ds, DCM_InstanceCreationTime, now.substr(8));
  const std::string number = Get(ds, DCM_SeriesNumber);
  Put(ds, DCM_SeriesNumber, std::to_string((number.empty() ? 0 : std::stoi(number)) + 9000));
  Put(ds,
      DCM_SeriesDescription,
      WithSuffix(Get(ds, DCM_SeriesDescription),
                 lossy ? " dcv lossy" : " dcv lossless",
                 64,
                 Get(ds, DCM_SpecificCharacterSet) == "ISO_IR 192"));
  const std::string versions = Get(ds, DCM_SoftwareVersions);
  Put(ds, DCM_SoftwareVersions, versions.empty() ? software : versions + "\\" + software);
  // The pixel module as the decoded values are stored; values in stored units of the original pixels go.
  PutPixelModule(ds, enc, columns, rows);
  for (const DcmTagKey & gone : { DCM_SmallestImagePixelValue,
                                  DCM_LargestImagePixelValue,
                                  DCM_SmallestPixelValueInSeries,
                                  DCM_LargestPixelValueInSeries,
                                  DCM_PixelPaddingValue,
                                  DCM_PixelPaddingRangeLimit,
                                  DCM_PlanarConfiguration,
                                  DCM_NumberOfFrames })
  {
    ds.findAndDeleteElement(gone);
  }
  // Private pixel data (odd groups 7F01-7FFF) describes pixels the decoded ones are not: it goes.
  for (unsigned long i = ds.card(); i-- > 0;)
  {
    const DcmTagKey t = ds.getElement(i)->getTag();
    if ((t.getGroup() & 1) && (t.getGroup() >> 8) == 0x7f)
      delete ds.remove(i);
  }
}
} // namespace

void
WriteDicomSeries(const FileHeader & header, std::size_t compressedBytes,
                 const std::function<void(int32_t z, std::vector<double> & values)> & slice,
                 const std::string & directory, bool force)
{
  const fs::path target(directory);
  if (fs::exists(target) && !fs::is_directory(target))
  {
    throw Failure("cannot write the DICOM series " + Quoted(directory) + ": it is a file, not a directory");
  }
  if (fs::is_directory(target) && !fs::is_empty(target) && !force)
  {
    throw Failure(Quoted(directory) + " is not empty; use --force to replace what it holds");
  }
  const fs::path parent = fs::absolute(target).parent_path();
  if (!fs::is_directory(parent))
  {
    throw Failure("cannot write " + Quoted(directory) + ": directory " + Quoted(parent.string()) + " does not exist");
  }
  std::map<std::string, std::string> m;
  for (const auto & [key, value] : header.metadata)
  {
    if (key.rfind("DICOM ", 0) == 0)
      m[key.substr(6)] = value;
  }
  const bool fromDicom = m.count("StudyInstanceUID") > 0;
  const auto get = [&m](const char * key, const std::string & otherwise = "") {
    const auto it = m.find(key);
    return it == m.end() ? otherwise : it->second;
  };
  const bool    ct = get("Modality") == "CT";
  const int32_t nx = header.size.x, ny = header.size.y, nz = header.size.z;
  if (nx > 65535 || ny > 65535)
  {
    throw Failure("cannot write " + Quoted(directory) + ": DICOM rows and columns are at most 65535");
  }

  // Stored pixels: the original's encoding when the volume came from DICOM, else the range in 16 bits.
  double              lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::vector<double> values;
  for (int32_t z = 0; z < nz; ++z)
  {
    slice(z, values);
    const auto r = std::minmax_element(values.begin(), values.end());
    lo = std::min(lo, *r.first);
    hi = std::max(hi, *r.second);
  }
  PixelEncoding enc;
  if (fromDicom && !get("RescaleSlope").empty())
  {
    enc.slope = std::stod(get("RescaleSlope", "1"));
    enc.intercept = std::stod(get("RescaleIntercept", "0"));
    enc.isSigned = get("PixelRepresentation", "0") == "1";
    enc.bitsStored = unsigned(std::clamp(std::stoi(get("BitsStored", "16")), 1, 16));
    KeepDecodedRange(enc, lo, hi);
  }
  else
  {
    const bool integer = IsInteger(header.pixelType);
    if (integer && lo >= -32768 && hi <= 32767)
    {
      enc.isSigned = true;
    }
    else if (integer && lo >= 0 && hi <= 65535)
    {
      enc.isSigned = false;
    }
    else
    {
      enc.intercept = lo;
      enc.slope = hi > lo ? (hi - lo) / 65535.0 : 1.0;
    }
  }
  const double storedMin = StoredMin(enc);
  const double storedMax = StoredMax(enc);

  const std::string series = NewUid();
  const std::string study = fromDicom ? get("StudyInstanceUID") : NewUid();
  const std::string frame = get("FrameOfReferenceUID", NewUid());
  const std::string now = [] {
    char              date[32];
    const std::time_t t = std::time(nullptr);
    std::strftime(date, sizeof(date), "%Y%m%d%H%M%S", std::gmtime(&t));
    return std::string(date);
  }();
  // A bounded-error file states its bound: 0 is lossless (not flagged lossy), above 0 near-lossless.
  const double bound = header.boundedLayer
                         ? ReadBoundedLayerHeader(header.residualLayer, header.size, "the .dcv file").maximumError
                         : -1.0;
  const bool   lossy = bound != 0.0;
  std::string  derivation = "Decoded from a DelaunayCompression .dcv file: lossy, a linear spline over an adaptive "
                            "Delaunay tetrahedralization";
  if (bound == 0.0)
    derivation = "Decoded from a DelaunayCompression .dcv file: lossless, every value the original's";
  else if (bound > 0.0)
    derivation = "Decoded from a DelaunayCompression .dcv file: near-lossless, every value within " + Decimal(bound) +
                 " of the original's";
  for (const auto & [key, value] : header.metadata)
  {
    if (key == "Resampled")
      derivation += "; the original series was resampled onto a regular grid (" + value + ")";
  }
  const double voxels = double(header.size.NumberOfVoxels());
  const double originalBytes = voxels * (enc.bitsStored > 8 ? 2.0 : 1.0);
  const double ratio = originalBytes / double(std::max<std::size_t>(1, compressedBytes));

  // The original files' headers (a .dcv file of a DICOM series on its own grid): one per slice.
  const StoredDicomHeaders stored = ParseDicomHeaders(header, "the .dcv file");
  const bool               headers = !stored.files.empty() && stored.files.size() == std::size_t(nz);

  const fs::path temporary = parent / (".dcv-" + std::to_string(::getpid()) + "-" + target.filename().string());
  fs::remove_all(temporary);
  fs::create_directories(temporary);
  const RemovedOnSignal registration(temporary.string(), true);
  try
  {
    std::vector<Uint16> pixels(std::size_t(nx) * std::size_t(ny));
    const auto &        d = header.direction; // row major: column j is axis j's direction
    for (int32_t z = 0; z < nz; ++z)
    {
      DcmFileFormat file(headers ? stored.files[std::size_t(z)].get() : nullptr);
      DcmDataset &  ds = *file.getDataset();
      if (headers)
      {
        Derive(ds, series, now, derivation, ratio, lossy, enc, nx, ny, std::string("dcv ") + ModuleVersion);
        CompleteType2(ds, z);
      }
      else
      {
        Put(ds, DCM_SOPClassUID, ct ? UID_CTImageStorage : UID_SecondaryCaptureImageStorage);
        Put(ds, DCM_SOPInstanceUID, NewUid());
        Put(ds, DCM_StudyInstanceUID, study);
        Put(ds, DCM_SeriesInstanceUID, series);
        Put(ds, DCM_FrameOfReferenceUID, frame);
        Put(ds, DCM_PositionReferenceIndicator, "");
        Put(ds, DCM_PatientName, get("PatientName", fromDicom ? "" : "DCV^PLACEHOLDER"));
        Put(ds, DCM_PatientID, get("PatientID", fromDicom ? "" : "DCV-" + series.substr(series.size() - 8)));
        Put(ds, DCM_PatientBirthDate, get("PatientBirthDate"));
        Put(ds, DCM_PatientSex, get("PatientSex"));
        Put(ds, DCM_StudyDate, get("StudyDate", now.substr(0, 8)));
        Put(ds, DCM_StudyTime, get("StudyTime", now.substr(8)));
        Put(ds, DCM_ReferringPhysicianName, get("ReferringPhysicianName"));
        Put(ds, DCM_StudyID, get("StudyID"));
        Put(ds, DCM_AccessionNumber, get("AccessionNumber"));
        if (!get("StudyDescription").empty() || !fromDicom)
          Put(ds, DCM_StudyDescription, get("StudyDescription", "Not from DICOM: placeholder study (dcv)"));
        Put(ds, DCM_Modality, get("Modality", "OT"));
        if (!get("BodyPartExamined").empty())
          Put(ds, DCM_BodyPartExamined, get("BodyPartExamined"));
        if (!ct || get("BodyPartExamined").empty())
          Put(ds, DCM_Laterality, ""); // type 2C: a paired body part (or one not known) needs it
        Put(ds, DCM_SeriesNumber, std::to_string(std::stoi(get("SeriesNumber", "0")) + 9000));
        Put(ds,
            DCM_SeriesDescription,
            (get("SeriesDescription") + (lossy ? " dcv lossy" : " dcv lossless")).substr(0, 64));
        Put(ds, DCM_Manufacturer, get("Manufacturer"));
        if (!get("ManufacturerModelName").empty())
          Put(ds, DCM_ManufacturerModelName, get("ManufacturerModelName"));
        if (!get("InstitutionName").empty())
          Put(ds, DCM_InstitutionName, get("InstitutionName"));
        Put(ds, DCM_SoftwareVersions, std::string("dcv ") + ModuleVersion);
        Put(ds, DCM_InstanceNumber, std::to_string(z + 1));
        Put(ds, DCM_ImageType, ct ? "DERIVED\\SECONDARY\\AXIAL" : "DERIVED\\SECONDARY");
        Put(ds, DCM_DerivationDescription, derivation);
        Put(ds, DCM_LossyImageCompression, lossy ? "01" : "00");
        if (lossy)
        {
          Put(ds, DCM_LossyImageCompressionRatio, Decimal(ratio));
          Put(ds, DCM_LossyImageCompressionMethod, "DCV");
        }
        Put(ds, DCM_ContentDate, now.substr(0, 8));
        Put(ds, DCM_ContentTime, now.substr(8));
        if (!ct)
        {
          Put(ds, DCM_ConversionType, "WSD");
          Put(ds, DCM_PatientOrientation, "");
        }
        else
        {
          Put(ds, DCM_KVP, get("KVP"));
          Put(ds, DCM_PatientPosition, get("PatientPosition")); // type 2C for CT
          Put(ds, DCM_AcquisitionNumber, "");
        }
        // Image plane: axis 0 along a row (columns), axis 1 down a column (rows).
        Put(ds, DCM_PixelSpacing, Decimal(header.spacing[1]) + "\\" + Decimal(header.spacing[0]));
        Put(ds,
            DCM_ImageOrientationPatient,
            Decimal(d[0]) + "\\" + Decimal(d[3]) + "\\" + Decimal(d[6]) + "\\" + Decimal(d[1]) + "\\" + Decimal(d[4]) +
              "\\" + Decimal(d[7]));
        std::string position;
        for (int r = 0; r < 3; ++r)
        {
          position += (r ? "\\" : "") + Decimal(header.origin[r] + d[3 * r + 2] * header.spacing[2] * z);
        }
        Put(ds, DCM_ImagePositionPatient, position);
        Put(ds, DCM_SliceThickness, get("SliceThickness", Decimal(header.spacing[2])));
        PutPixelModule(ds, enc, nx, ny);
        if (!ct)
          Put(ds, DCM_RescaleType, "US");
      }
      slice(z, values);
      for (std::size_t i = 0; i < pixels.size(); ++i)
      {
        const double stored = std::clamp(std::round((values[i] - enc.intercept) / enc.slope), storedMin, storedMax);
        pixels[i] = enc.isSigned ? Uint16(Sint16(stored)) : Uint16(stored);
      }
      if (ds.putAndInsertUint16Array(DCM_PixelData, pixels.data(), unsigned(pixels.size())).bad())
      {
        throw Failure("cannot store the pixel data of slice " + std::to_string(z + 1));
      }
      char name[32];
      std::snprintf(name, sizeof(name), "IM%06d.dcm", int(z + 1));
      const OFCondition c = file.saveFile((temporary / name).string().c_str(), EXS_LittleEndianExplicit);
      if (c.bad())
      {
        throw Failure("cannot write " + Quoted((target / name).string()) + ": " + c.text());
      }
    }
    const fs::path old = parent / (".dcv-" + std::to_string(::getpid()) + "-old-" + target.filename().string());
    const bool     replacing = force && fs::exists(target);
    if (replacing)
    {
      fs::rename(target, old);
    }
    // Without --force, rename() itself refuses a directory that became non-empty meanwhile.
    std::error_code error;
    fs::rename(temporary, target, error);
    if (error)
    {
      std::error_code ignored;
      if (replacing)
        fs::rename(old, target, ignored); // the old series back

      throw Failure("cannot write the DICOM series " + Quoted(directory) + ": " +
                    (fs::is_directory(target) && !fs::is_empty(target)
                       ? std::string("files appeared in it while it was being written (another run?); they are kept, "
                                     "use --force to replace them")
                       : error.message()));
    }
    fs::remove_all(old);
  }
  catch (...)
  {
    std::error_code ignored;
    fs::remove_all(temporary, ignored);
    throw;
  }
}

std::string
DicomLibraryVersion()
{
  return std::string("DCMTK ") + OFFIS_DCMTK_VERSION_STRING;
}

} // namespace dcv::tools
