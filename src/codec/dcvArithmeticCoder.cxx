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
#include "dcvArithmeticCoder.h"

#include <cmath>
#include <stdexcept>

namespace dcv
{

// ---------------------------------------------------------------------------------------------
// Encoder

ArithmeticEncoder::ArithmeticEncoder(std::vector<uint8_t> & out)
  : m_Out(&out)
  , m_Start(out.size())
{}

void
ArithmeticEncoder::ShiftLow()
{
  // low holds up to 33 bits: bits 24..31 are the next byte, bit 32 a carry into the bytes pending
  // (m_Cache followed by m_CacheSize - 1 bytes 0xFF, which the carry turns into 0x00).
  if (m_Low < 0xFF000000u || m_Low >= (uint64_t(1) << 32))
  {
    const uint8_t carry = uint8_t(m_Low >> 32);
    uint8_t       byte = m_Cache;
    do
    {
      if (m_First)
      {
        m_First = false; // LZMA's first byte: always 0 (nothing can carry into it), not written
      }
      else
      {
        m_Out->push_back(uint8_t(byte + carry));
      }
      byte = 0xFF;
    } while (--m_CacheSize != 0);
    m_Cache = uint8_t(m_Low >> 24);
  }
  ++m_CacheSize;
  m_Low = (m_Low & 0x00FFFFFFu) << 8;
}

void
ArithmeticEncoder::EncodeEquiprobable(uint32_t value, int bits)
{
  if (bits < 0 || bits > 32)
  {
    throw std::invalid_argument("ArithmeticEncoder::EncodeEquiprobable: bits must be in [0, 32]");
  }
  for (int i = bits - 1; i >= 0; --i)
  {
    m_Range >>= 1;
    if ((value >> i) & 1u)
    {
      m_Low += m_Range;
    }
    Normalize();
  }
}

void
ArithmeticEncoder::Finish()
{
  if (m_Finished)
  {
    return;
  }
  for (int i = 0; i < 5; ++i)
  {
    ShiftLow();
  }
  m_Finished = true;
}

double
ArithmeticEncoder::GetBitCount() const
{
  if (m_Finished)
  {
    return 8.0 * double(m_Out->size() - m_Start);
  }
  // Bytes out, pending bytes, and the information held in the range.
  return 8.0 * double(m_Out->size() - m_Start + m_CacheSize) + 32.0 - std::log2(double(m_Range));
}

// ---------------------------------------------------------------------------------------------
// Decoder

ArithmeticDecoder::ArithmeticDecoder(const uint8_t * data, std::size_t size)
  : m_Data(data)
  , m_Size(data ? size : 0)
{
  for (int i = 0; i < 4; ++i)
  {
    m_Code = (m_Code << 8) | NextByte();
  }
}

uint32_t
ArithmeticDecoder::DecodeEquiprobable(int bits)
{
  if (bits < 0 || bits > 32)
  {
    throw std::invalid_argument("ArithmeticDecoder::DecodeEquiprobable: bits must be in [0, 32]");
  }
  uint32_t value = 0;
  for (int i = 0; i < bits; ++i)
  {
    m_Range >>= 1;
    uint32_t bit = 0;
    if (m_Code >= m_Range)
    {
      m_Code -= m_Range;
      bit = 1;
    }
    value = (value << 1) | bit;
    Normalize();
  }
  return value;
}

// ---------------------------------------------------------------------------------------------
// Integers

UIntModel::UIntModel(int maximumShift)
{
  m_Prefix.fill(BitModel(maximumShift));
  for (auto & row : m_Mantissa)
  {
    row.fill(BitModel(maximumShift));
  }
}

void
UIntModel::Encode(ArithmeticEncoder & encoder, uint32_t value)
{
  const uint64_t v = uint64_t(value) + 1; // in [1, 2^32]
  int            e = 0;
  while ((v >> (e + 1)) != 0)
  {
    ++e;
  }
  // e in unary: e ones, then a zero unless e is the largest possible (32).
  for (int i = 0; i < e; ++i)
  {
    encoder.Encode(m_Prefix[i], 1);
  }
  if (e < 32)
  {
    encoder.Encode(m_Prefix[e], 0);
  }
  else
  {
    return; // v == 2^32: no mantissa
  }
  // The e bits below the leading one: the first ones through a small binary tree of models.
  int node = 1;
  for (int i = e - 1; i >= 0; --i)
  {
    const int bit = int((v >> i) & 1u);
    if (e - 1 - i < AdaptiveMantissaBits)
    {
      encoder.Encode(m_Mantissa[e][node], bit);
      node = 2 * node + bit;
    }
    else
    {
      encoder.EncodeEquiprobable(uint32_t(v) & ((1u << (i + 1)) - 1u), i + 1);
      break;
    }
  }
}

uint32_t
UIntModel::Decode(ArithmeticDecoder & decoder)
{
  int e = 0;
  while (e < 32 && decoder.Decode(m_Prefix[e]))
  {
    ++e;
  }
  if (e == 32)
  {
    return 0xFFFFFFFFu;
  }
  uint64_t v = 1;
  int      node = 1;
  for (int i = e - 1; i >= 0; --i)
  {
    if (e - 1 - i < AdaptiveMantissaBits)
    {
      const int bit = decoder.Decode(m_Mantissa[e][node]);
      node = 2 * node + bit;
      v = (v << 1) | uint64_t(bit);
    }
    else
    {
      v = (v << (i + 1)) | decoder.DecodeEquiprobable(i + 1);
      break;
    }
  }
  return uint32_t(v - 1);
}

SIntModel::SIntModel(int maximumShift)
  : m_Zero(maximumShift)
  , m_Sign(maximumShift)
  , m_Magnitude(maximumShift)
{}

void
SIntModel::EncodeNonZero(ArithmeticEncoder & encoder, int32_t value)
{
  encoder.Encode(m_Sign, value < 0);
  const uint32_t magnitude = value < 0 ? uint32_t(0) - uint32_t(value) : uint32_t(value);
  m_Magnitude.Encode(encoder, magnitude - 1);
}

int32_t
SIntModel::DecodeNonZero(ArithmeticDecoder & decoder)
{
  const bool     negative = decoder.Decode(m_Sign) != 0;
  const uint32_t magnitude = m_Magnitude.Decode(decoder) + 1u; // wraps to 0 on garbage: harmless
  // Modular conversion (defined since C++20, and what every supported compiler does): garbage
  // magnitudes of 2^31 and more wrap around.
  return int32_t(negative ? uint32_t(0) - magnitude : magnitude);
}

} // namespace dcv
