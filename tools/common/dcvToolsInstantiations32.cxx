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
// dcvTools.h's reading, writing and decoding of volumes for the pixel types uint32_t and int32_t, compiled once for
// every program; dcvToolsInstantiations{8,16,32,Real}.cxx compile in parallel.
#include "dcvTools.h"

namespace dcv::tools
{
DCV_TOOLS_INSTANTIATION(, uint32_t);
DCV_TOOLS_INSTANTIATION(, int32_t);
} // namespace dcv::tools
