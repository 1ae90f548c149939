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
#include "dcvDicom.h"
#include "dcvDicomHeader.h"
#include "dcvGDCM.h"
#include "dcvTools.h"

#include "itkImageIOFactory.h"
#include "itkMetaDataObject.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

namespace fs = std::filesystem;

namespace dcv::tools
{
namespace
{
std::string
Trimmed(std::string s)
{
  const auto first = s.find_first_not_of(" \t\r\n");
  const auto last = s.find_last_not_of(" \t\r\n");
  return first == std::string::npos ? std::string() : s.substr(first, last - first + 1);
}

std::string
Tag(const itk::MetaDataDictionary & d, const std::string & key)
{
  std::string value;
  itk::ExposeMetaData<std::string>(d, key, value);
  return Trimmed(value);
}

/** The numbers of a multi-valued decimal string ("a\\b\\c"); none where one does not parse. */
std::vector<double>
Numbers(const std::string & value)
{
  std::vector<double> numbers;
  std::stringstream   in(value);
  for (std::string item; std::getline(in, item, '\\');)
  {
    try
    {
      std::size_t used = 0;
      numbers.push_back(std::stod(item, &used));
      if (!Trimmed(item.substr(used)).empty() || !std::isfinite(numbers.back()))
        return {};
    }
    catch (const std::exception &)
    {
      return {};
    }
  }
  return numbers;
}

constexpr const char * SecondaryCaptureImageStorage = "1.2.840.10008.5.1.4.1.1.7";

/** The header of one file (GDCM reads up to the pixel data). */
itk::ImageIOBase::Pointer
ReadHeader(const std::string & file)
{
  auto io = GDCM().newImageIO();
  io->SetFileName(file);
  try
  {
    io->ReadImageInformation();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(file) + ": " + e.GetDescription());
  }
  return io;
}

std::string
Number(double v)
{
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

std::string
Millimetres(double v)
{
  return Number(v) + " mm";
}

double
Dot(const std::array<double, 3> & a, const std::array<double, 3> & b)
{
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

std::array<double, 3>
Minus(const std::array<double, 3> & a, const std::array<double, 3> & b)
{
  return { { a[0] - b[0], a[1] - b[1], a[2] - b[2] } };
}

std::array<double, 3>
Scaled(const std::array<double, 3> & a, double f)
{
  return { { a[0] * f, a[1] * f, a[2] * f } };
}

double
Norm(const std::array<double, 3> & a)
{
  return std::sqrt(Dot(a, a));
}

const char * const ResampleHint = "; --resample resamples it onto a regular grid instead";
} // namespace

bool
IsDicomInput(const std::string & path)
{
  if (fs::is_directory(path))
  {
    return true;
  }
  if (!fs::is_regular_file(path))
  {
    return false;
  }
  if (StartsAsDicom(path))
  {
    // GDCM aborts on a file cut short inside its header: refused before GDCM reads it, or its series.
    CheckDicomHeaders(fs::path(path).parent_path().string());
  }
  // The other formats first, so that GDCM is loaded only for what none of them reads.
  if (const auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode))
  {
    return std::string(io->GetNameOfClass()) == "GDCMImageIO"; // registered once GDCM was loaded
  }
  return GDCM().newImageIO()->CanReadFile(path.c_str());
}

DicomSeriesList
ListDicomSeries(const std::string & directory)
{
  CheckDicomHeaders(directory); // GDCM's scan aborts on a file cut short inside its header
  return ListCheckedDicomSeries(directory);
}

DicomSeriesList
ListCheckedDicomSeries(const std::string & directory)
{
  const auto & gdcm = GDCM();
  try
  {
    return gdcm.seriesFileNames(directory);
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot list the DICOM series of " + Quoted(directory) + ": " + e.GetDescription());
  }
}

DicomSeries
FindDicomSeries(const std::string & path, const std::string & uid, std::size_t & skipped)
{
  const fs::path directory = fs::is_directory(path) ? fs::path(path) : fs::path(path).parent_path();
  std::string    wanted = uid;
  if (!fs::is_directory(path) && wanted.empty())
  {
    // One file stands for its series.
    wanted = Tag(ReadHeader(path)->GetMetaDataDictionary(), "0020|000e");
  }
  const auto  headers = CheckDicomHeaders(directory.string());
  const auto  listed = ListCheckedDicomSeries(directory.string());
  std::size_t files = 0, dicom = 0;
  for (const auto & entry : fs::directory_iterator(directory))
  {
    files += entry.is_regular_file() ? 1 : 0;
  }
  std::vector<DicomSeries> all;
  for (const auto & [u, seriesFiles] : listed)
  {
    DicomSeries s;
    s.uid = u;
    s.files = seriesFiles;
    dicom += s.files.size();
    if (!s.files.empty())
    {
      const auto io = ReadHeader(s.files.front());
      s.uid = Tag(io->GetMetaDataDictionary(), "0020|000e");
      s.description = Tag(io->GetMetaDataDictionary(), "0008|103e");
      s.modality = Tag(io->GetMetaDataDictionary(), "0008|0060");
      s.columns = unsigned(io->GetDimensions(0));
      s.rows = unsigned(io->GetDimensions(1));
    }
    all.push_back(std::move(s));
  }
  skipped = files - std::min(files, dicom);
  if (all.empty())
  {
    throw Failure("no DICOM image in " + Quoted(directory.string()) +
                  (files ? " (" + std::to_string(files) + " files, none of them DICOM)" : " (it is empty)"));
  }
  // GDCM's scan leaves out an image of the series without pixel data (at either end it would go unseen).
  const auto whole = [&](const DicomSeries & s) {
    for (const auto & h : headers)
    {
      if (h.image && !h.pixelData && h.seriesUid == s.uid &&
          std::none_of(s.files.begin(), s.files.end(), [&](const std::string & f) {
            std::error_code error;
            return fs::equivalent(f, h.file, error);
          }))
      {
        CheckDicomPixelData(h.file); // Failure naming the file
      }
    }
    return s;
  };
  if (!wanted.empty())
  {
    for (const auto & s : all)
    {
      if (s.uid == wanted)
        return whole(s);
    }
  }
  if (all.size() == 1 && wanted.empty())
  {
    return whole(all.front());
  }
  std::ostringstream list;
  list << (wanted.empty() ? Quoted(directory.string()) + " holds " + std::to_string(all.size()) +
                              " DICOM series; choose one with --series UID:"
                          : "no series " + Quoted(wanted) + " in " + Quoted(directory.string()) + "; it holds:");
  for (const auto & s : all)
  {
    list << "\n  " << s.uid << "  " << (s.modality.empty() ? "?" : s.modality) << "  " << s.files.size() << " slices  "
         << s.columns << "x" << s.rows << "  " << Quoted(s.description);
  }
  throw Failure(list.str());
}

PixelType
DicomPixelType(const DicomSeries & series)
{
  const auto io = ReadHeader(series.files.front());
  try
  {
    return itk::DCVPixelType(io->GetComponentType(), Quoted(series.files.front()));
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure(e.GetDescription());
  }
}

std::vector<std::pair<std::string, std::string>>
DicomMetadata(const DicomSeries & series)
{
  // The attributes a derived series keeps (DICOM PS3.3: patient, general study, frame of reference,
  // general series and equipment, acquisition), by keyword.
  static const std::pair<const char *, const char *> kept[] = {
    { "0010|0010", "PatientName" },
    { "0010|0020", "PatientID" },
    { "0010|0030", "PatientBirthDate" },
    { "0010|0040", "PatientSex" },
    { "0020|000d", "StudyInstanceUID" },
    { "0008|0020", "StudyDate" },
    { "0008|0030", "StudyTime" },
    { "0020|0010", "StudyID" },
    { "0008|0050", "AccessionNumber" },
    { "0008|0090", "ReferringPhysicianName" },
    { "0008|1030", "StudyDescription" },
    { "0020|0052", "FrameOfReferenceUID" },
    { "0008|0060", "Modality" },
    { "0018|0015", "BodyPartExamined" },
    { "0020|000e", "SeriesInstanceUID" },
    { "0020|0011", "SeriesNumber" },
    { "0008|103e", "SeriesDescription" },
    { "0008|0070", "Manufacturer" },
    { "0008|1090", "ManufacturerModelName" },
    { "0008|0080", "InstitutionName" },
    { "0018|0050", "SliceThickness" },
    { "0018|0060", "KVP" },
    { "0008|0022", "AcquisitionDate" },
    { "0020|0037", "ImageOrientationPatient" },
    { "0018|5100", "PatientPosition" },
    { "0028|1052", "RescaleIntercept" },
    { "0028|1053", "RescaleSlope" },
    { "0028|0101", "BitsStored" },
    { "0028|0103", "PixelRepresentation" },
  };
  const auto                                       io = ReadHeader(series.files.front());
  std::vector<std::pair<std::string, std::string>> metadata;
  for (const auto & [tag, keyword] : kept)
  {
    const std::string value = Tag(io->GetMetaDataDictionary(), tag);
    if (!value.empty())
    {
      metadata.emplace_back(std::string("DICOM ") + keyword, value);
    }
  }
  return metadata;
}

std::vector<DicomSlice>
ReadDicomSlices(const DicomSeries & series)
{
  std::vector<DicomSlice> slices;
  for (const auto & file : series.files)
  {
    const auto io = ReadHeader(file);
    DicomSlice s;
    for (unsigned d = 0; d < 3; ++d)
    {
      s.position[d] = io->GetOrigin(d);
      s.orientation[d] = io->GetDirection(0)[d];
      s.orientation[3 + d] = io->GetDirection(1)[d];
    }
    s.pixelSpacing = { { io->GetSpacing(0), io->GetSpacing(1) } };
    s.columns = unsigned(io->GetDimensions(0));
    s.rows = unsigned(io->GetDimensions(1));
    const itk::MetaDataDictionary & d = io->GetMetaDataDictionary();
    if (Tag(d, "0008|0016") == SecondaryCaptureImageStorage)
    {
      // GDCM reads no image plane in a Secondary Capture image (its IOD has none): every slice would be
      // at the origin, 1 mm apart in the plane. dcv writes the plane into the series it makes from
      // volumes that were not CT; where it is there, it is read here (ReadVolume's grid comes from it).
      const auto position = Numbers(Tag(d, "0020|0032"));
      const auto orientation = Numbers(Tag(d, "0020|0037"));
      const auto spacing = Numbers(Tag(d, "0028|0030")); // between rows, then between columns
      s.positioned = position.size() == 3;
      if (s.positioned)
        std::copy(position.begin(), position.end(), s.position.begin());
      if (orientation.size() == 6)
        std::copy(orientation.begin(), orientation.end(), s.orientation.begin());
      if (spacing.size() == 2 && spacing[0] > 0.0 && spacing[1] > 0.0)
        s.pixelSpacing = { { spacing[1], spacing[0] } };
    }
    slices.push_back(s);
  }
  return slices;
}

DicomResampling
CheckDicomSlices(const std::string & name, const std::vector<DicomSlice> & slices, bool resample)
{
  if (slices.size() < 2)
  {
    throw Failure(name + " has " + std::to_string(slices.size()) + " slice; a volume needs at least 2");
  }
  const DicomSlice & first = slices.front();
  for (std::size_t i = 1; i < slices.size(); ++i)
  {
    if (slices[i].rows != first.rows || slices[i].columns != first.columns)
    {
      throw Failure(name + ": slices of different size (" + std::to_string(first.columns) + "x" +
                    std::to_string(first.rows) + " and " + std::to_string(slices[i].columns) + "x" +
                    std::to_string(slices[i].rows) + " at slice " + std::to_string(i + 1) + ")");
    }
    for (int k = 0; k < 6; ++k)
    {
      if (std::abs(slices[i].orientation[k] - first.orientation[k]) > 1e-4)
      {
        throw Failure(name + ": slices of different orientation (slice " + std::to_string(i + 1) +
                      " differs from the first)");
      }
    }
  }
  const auto &                o = first.orientation;
  const std::array<double, 3> normal{
    { o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5], o[0] * o[4] - o[1] * o[3] }
  };
  // Each slice's position relative to the first: along the normal, and the offset across it.
  std::vector<double>                along(slices.size(), 0.0);
  std::vector<std::array<double, 3>> across(slices.size(), { { 0, 0, 0 } });
  for (std::size_t i = 1; i < slices.size(); ++i)
  {
    const auto d = Minus(slices[i].position, first.position);
    along[i] = Dot(d, normal);
    across[i] = Minus(d, Scaled(normal, along[i]));
  }
  bool                tilted = false;
  std::vector<double> gaps;
  for (std::size_t i = 1; i < slices.size(); ++i)
  {
    const double gap = along[i] - along[i - 1];
    const double offset = Norm(Minus(across[i], across[i - 1]));
    if (offset > 1e-3 * std::max(1.0, std::abs(gap)) && !tilted)
    {
      if (!resample)
      {
        throw Failure(name + ": slices " + std::to_string(i) + " and " + std::to_string(i + 1) +
                      " are not stacked along the normal of their orientation (offset " + Millimetres(offset) +
                      " across it: gantry tilt?); a tilted series is not a volume on a grid" + ResampleHint);
      }
      tilted = true;
    }
    gaps.push_back(gap);
  }
  std::vector<double> sorted(gaps);
  std::sort(sorted.begin(), sorted.end());
  const double usual = sorted[sorted.size() / 2];
  if (!(std::abs(usual) > 1e-6) || (resample && !(sorted.front() * usual > 1e-12 && sorted.back() * usual > 1e-12)))
  {
    const auto unplaced =
      std::find_if(slices.begin(), slices.end(), [](const DicomSlice & s) { return !s.positioned; });
    if (unplaced != slices.end())
    {
      throw Failure(name + ": slice " + std::to_string(unplaced - slices.begin() + 1) +
                    " is a Secondary Capture image without Image Position (Patient): no position to stack it by");
    }
    throw Failure(name + ": slices at the same position (duplicates?)");
  }
  bool uneven = false;
  for (std::size_t i = 0; i < gaps.size(); ++i)
  {
    if (std::abs(gaps[i] - usual) > 1e-3 * std::abs(usual) + 1e-4)
    {
      const double ratio = gaps[i] / usual;
      const bool   missing = ratio > 1.5 && std::abs(ratio - std::round(ratio)) < 0.05;
      // Resampling would make up the missing slices: they stay refused.
      if (missing || !resample)
      {
        throw Failure(
          name + (missing
                    ? ": missing slice" + std::string(std::round(ratio) > 2.0 ? "s" : "") + " between slices " +
                        std::to_string(i + 1) + " and " + std::to_string(i + 2) + " (a gap of " + Millimetres(gaps[i]) +
                        " where slices are " + Millimetres(usual) + " apart)"
                    : ": uneven slice spacing: " + Millimetres(gaps[i]) + " between slices " + std::to_string(i + 1) +
                        " and " + std::to_string(i + 2) + ", " + Millimetres(usual) + " elsewhere" + ResampleHint));
      }
      uneven = true;
    }
  }
  DicomResampling r;
  // The grid's third axis points from the first slice to the last, as ITK's series reader orients it.
  const double sign = usual > 0.0 ? 1.0 : -1.0;
  for (auto & a : along)
  {
    a *= sign;
  }
  r.needed = tilted || uneven;
  r.uneven = uneven;
  r.tilted = tilted;
  r.along = along;
  r.origin = first.position;
  r.rows = first.rows;
  r.columns = first.columns;
  for (int d = 0; d < 3; ++d)
  {
    r.direction[3 * d + 0] = o[d];
    r.direction[3 * d + 1] = o[3 + d];
    r.direction[3 * d + 2] = sign * normal[d];
  }
  if (tilted)
  {
    // One gantry tilt offsets the slices across the normal in proportion to their distance along it:
    // the least-squares offset per mm, which every slice must follow within a twentieth of a pixel.
    double tt = 0.0;
    for (std::size_t i = 0; i < slices.size(); ++i)
    {
      tt += along[i] * along[i];
      for (int d = 0; d < 3; ++d)
        r.shear[d] += along[i] * across[i][d];
    }
    r.shear = Scaled(r.shear, 1.0 / tt);
    const double tolerance = 0.05 * std::min(first.pixelSpacing[0], first.pixelSpacing[1]);
    for (std::size_t i = 0; i < slices.size(); ++i)
    {
      if (Norm(Minus(across[i], Scaled(r.shear, along[i]))) > tolerance)
      {
        throw Failure(name + ": the slices are offset across the normal of their orientation, but not in " +
                      "proportion to their distance along it (slice " + std::to_string(i + 1) +
                      "): not one gantry tilt, so not resampled");
      }
    }
  }
  const double extent = along.back();
  r.spacing[0] = first.pixelSpacing[0];
  r.spacing[1] = first.pixelSpacing[1];
  if (!r.needed)
  {
    r.spacing[2] = extent / double(slices.size() - 1);
    r.slices = slices.size();
    return r;
  }
  std::string spacing;
  if (uneven)
  {
    // The smallest gap, so that no part of the series is sampled more coarsely than it was, shortened
    // where needed so that the grid ends on the last slice.
    double smallest = std::abs(gaps.front()), largest = smallest;
    for (const double g : gaps)
    {
      smallest = std::min(smallest, std::abs(g));
      largest = std::max(largest, std::abs(g));
    }
    const double intervals = std::max(1.0, std::ceil(extent / smallest - 1e-3));
    r.spacing[2] = extent / intervals;
    r.slices = std::size_t(intervals) + 1;
    spacing = Millimetres(r.spacing[2]) + (std::abs(r.spacing[2] - smallest) < 1e-6
                                             ? std::string(" (the smallest gap)")
                                             : " (the smallest gap, " + Millimetres(smallest) + ", fitted to the " +
                                                 Millimetres(extent) + " from the first slice to the last)");
    r.description = "uneven slice spacing " + Number(smallest) + "-" + Millimetres(largest);
    // A stray near-duplicate would otherwise make a volume of thousands of slices.
    if (r.slices > 4 * slices.size())
    {
      throw Failure(name + ": " + r.description + "; resampling onto the smallest gap would make " +
                    std::to_string(r.slices) + " slices of " + std::to_string(slices.size()) + ", so not resampled");
    }
  }
  else
  {
    r.spacing[2] = extent / double(slices.size() - 1);
    r.slices = slices.size();
    spacing = Millimetres(r.spacing[2]) + " apart";
  }
  if (tilted)
  {
    const double degrees = std::atan(Norm(r.shear)) * 180.0 / 3.14159265358979323846;
    r.description = "gantry tilt " + Number(degrees) + " degrees" + (uneven ? " and " + r.description : "") +
                    " -> slices along the normal of the orientation, " + spacing;
  }
  else
  {
    r.description += " -> " + spacing;
  }
  r.description += ", " + std::to_string(r.slices) + " slices";
  return r;
}

} // namespace dcv::tools
