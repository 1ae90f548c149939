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
// The encoder of include/itkDCVEncoder.h for the integer pixel types of .dcv, compiled once for every
// program (the floating-point types are in itkDCVEncoderReals.cxx: the two compile in parallel).
#include "itkDCVEncoder.h"

namespace itk
{
DCV_ENCODER_INSTANTIATION(, uint8_t);
DCV_ENCODER_INSTANTIATION(, int8_t);
DCV_ENCODER_INSTANTIATION(, uint16_t);
DCV_ENCODER_INSTANTIATION(, int16_t);
DCV_ENCODER_INSTANTIATION(, uint32_t);
DCV_ENCODER_INSTANTIATION(, int32_t);
} // namespace itk
