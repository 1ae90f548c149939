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
#ifndef dcvPhantom_h
#define dcvPhantom_h

#include "DelaunayCompressionExport.h"
#include "dcvRasterizer.h"

#include <vector>

namespace dcv
{

/** The 3D Shepp-Logan head phantom (Kak and Slaney's ten ellipsoids, with the higher-contrast
 * intensities of the "modified" variant) sampled at voxel centres of a grid spanning [-1, 1]^3,
 * scaled so that the skull is 255. A volume the project makes itself, for the demo and tests. */
DelaunayCompression_EXPORT std::vector<uint8_t>
                           SheppLoganPhantom(const GridSize & grid);

} // namespace dcv

#endif
