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
#ifndef dcvDicomTestUtilities_h
#define dcvDicomTestUtilities_h

// DICOM series the tests make themselves (DCMTK), so that the DICOM tests built on them need no data.
#include <dcmtk/dcmdata/dctk.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace dcv::test
{

/** A small CT series written with DCMTK, as a scanner stores one (12 bits stored, unsigned, rescale
 * intercept -1024, so the stored range ends at -1024 HU): `size` x `size` pixels of 1 mm, slice k at
 * positions[k] with the orientation `orientation` (row and column cosines), values hu(i, j, k, point) in
 * HU. Needs no data, so the tests built on it always run. */
inline void
WriteCtSeries(const std::string & directory, int size, const std::vector<std::array<double, 3>> & positions,
              const std::array<double, 6> &                                                       orientation,
              const std::function<double(int i, int j, int k, const std::array<double, 3> & p)> & hu)
{
  std::filesystem::create_directories(directory);
  const auto decimal = [](double v) {
    std::ostringstream s;
    s.precision(10);
    s << v;
    return s.str();
  };
  std::string cosines;
  for (int d = 0; d < 6; ++d)
    cosines += (d ? "\\" : "") + decimal(orientation[d]);
  const std::string root = "1.2.826.0.1.3680043.2.1125.77";
  for (std::size_t k = 0; k < positions.size(); ++k)
  {
    DcmFileFormat file;
    DcmDataset &  ds = *file.getDataset();
    const auto    put = [&ds](const DcmTagKey & key, const std::string & value) {
      ASSERT_TRUE(ds.putAndInsertString(key, value.c_str()).good()) << value;
    };
    put(DCM_SOPClassUID, UID_CTImageStorage);
    put(DCM_SOPInstanceUID, root + ".3." + std::to_string(k + 1));
    put(DCM_StudyInstanceUID, root + ".1");
    put(DCM_SeriesInstanceUID, root + ".2");
    put(DCM_FrameOfReferenceUID, root + ".4");
    put(DCM_PatientName, "SYNTHETIC^CT");
    put(DCM_PatientID, "DCV-SYNTHETIC");
    put(DCM_StudyDate, "20240101");
    put(DCM_StudyTime, "120000");
    put(DCM_Modality, "CT");
    put(DCM_SeriesNumber, "3");
    put(DCM_InstanceNumber, std::to_string(k + 1));
    put(DCM_ImageType, "ORIGINAL\\PRIMARY\\AXIAL");
    put(DCM_ImagePositionPatient,
        decimal(positions[k][0]) + "\\" + decimal(positions[k][1]) + "\\" + decimal(positions[k][2]));
    put(DCM_ImageOrientationPatient, cosines);
    put(DCM_PixelSpacing, "1\\1");
    put(DCM_SliceThickness, "2");
    put(DCM_SamplesPerPixel, "1");
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
    put(DCM_Rows, std::to_string(size));
    put(DCM_Columns, std::to_string(size));
    put(DCM_BitsAllocated, "16");
    put(DCM_BitsStored, "12");
    put(DCM_HighBit, "11");
    put(DCM_PixelRepresentation, "0");
    put(DCM_RescaleIntercept, "-1024");
    put(DCM_RescaleSlope, "1");
    std::vector<Uint16> pixels(std::size_t(size) * std::size_t(size));
    for (int j = 0; j < size; ++j)
    {
      for (int i = 0; i < size; ++i)
      {
        std::array<double, 3> p;
        for (int d = 0; d < 3; ++d)
          p[d] = positions[k][d] + i * orientation[d] + j * orientation[3 + d];
        pixels[std::size_t(j) * size + i] = Uint16(std::clamp(std::round(hu(i, j, int(k), p) + 1024.0), 0.0, 4095.0));
      }
    }
    ASSERT_TRUE(ds.putAndInsertUint16Array(DCM_PixelData, pixels.data(), unsigned(pixels.size())).good());
    char name[32];
    std::snprintf(name, sizeof(name), "S%03d.dcm", int(k + 1));
    ASSERT_TRUE(file.saveFile((directory + "/" + name).c_str(), EXS_LittleEndianExplicit).good()) << name;
  }
}

/** Axial slices at the given z (mm). */
inline std::vector<std::array<double, 3>>
AxialPositions(const std::vector<double> & z)
{
  std::vector<std::array<double, 3>> p;
  for (const double v : z)
    p.push_back({ { -20.0, 10.0, v } });
  return p;
}

constexpr std::array<double, 6> Axial{ { 1, 0, 0, 0, 1, 0 } };

} // namespace dcv::test

#endif
