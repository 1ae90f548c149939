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
#ifndef dcvBoundedEncoder_h
#define dcvBoundedEncoder_h

// Internal to the compiled sources: dcv::Encode's bounded-error mode.
#include "dcvEncoder.h"

namespace dcv
{
/** The .dcv file of the input within options.maximumError of every voxel (dcv::Encode calls it when the
 * option is set): a constant spline and a bounded-error layer. Reads input.exact. */
EncoderResult
EncodeBounded(const EncoderInput & input, const EncoderOptions & options);
} // namespace dcv

#endif
