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
#ifndef dcvArithmeticCoder_h
#define dcvArithmeticCoder_h

#include "DelaunayCompressionExport.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

/** \file dcvArithmeticCoder.h
 * Adaptive binary arithmetic coding, the entropy-coding core of the .dcv format: a range coder in
 * the style of LZMA's (32-bit range, 64-bit low with carry propagation into the bytes already
 * written, byte-wise renormalization) driven by adaptive bit probabilities, plus adaptive codes for
 * unsigned and signed integers built on it.
 *
 * Stream layout: the bytes of the range coder only (LZMA's always-zero leading byte is not
 * written). Finish() flushes 4 bytes, and a decoder performing the same sequence of operations
 * reads exactly the bytes that were written, never more: reading past the end therefore means a
 * truncated or corrupt stream, which the decoder reports through Overrun() (it then reads zeros).
 * Any byte sequence decodes to *some* values without undefined behaviour.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** Adaptive probability of a binary event: P(bit == 0) as a 16-bit integer, moved towards each
 * coded bit by a shift. The shift starts at 1 and grows with the number of bits seen (a rate of
 * about 1 / (count + 2), the Krichevsky-Trofimov estimate) up to `maximumShift`, so a fresh model
 * learns fast and a trained one is stable. */
class BitModel
{
public:
  static constexpr int      ProbabilityBits = 16;
  static constexpr uint32_t One = 1u << ProbabilityBits;

  explicit BitModel(int maximumShift = 5)
    : m_MaximumShift(uint8_t(maximumShift < 1 ? 1 : (maximumShift > 15 ? 15 : maximumShift)))
  {}

  /** A model starting from a prior: P(bit == 0) = probability / 2^16 (clamped to [1, 2^16 - 1]),
   * trusted as if `count` bits had been seen (count 0: the first bit moves it half way). */
  BitModel(int maximumShift, uint32_t probability, int count)
    : BitModel(maximumShift)
  {
    m_Probability = uint16_t(probability < 1 ? 1 : (probability > One - 1 ? One - 1 : probability));
    m_Count = uint8_t(count < 0 ? 0 : (count > int(sizeof(ShiftTable)) - 1 ? int(sizeof(ShiftTable)) - 1 : count));
  }

  /** P(bit == 0) * 2^16, in [1, 2^16 - 1]. */
  uint32_t
  GetProbability() const
  {
    return m_Probability;
  }

  void
  Update(int bit)
  {
    const int shift = ShiftTable[m_Count] < m_MaximumShift ? ShiftTable[m_Count] : m_MaximumShift;
    if (m_Count < sizeof(ShiftTable) - 1)
    {
      ++m_Count;
    }
    if (bit)
    {
      m_Probability -= m_Probability >> shift;
    }
    else
    {
      m_Probability += (One - m_Probability) >> shift;
    }
  }

private:
  /** round(log2(count + 2)), up to 7: the shift whose rate is closest to 1 / (count + 2). */
  static constexpr uint8_t ShiftTable[128] = { 1, 2, 2, 2, 3, 3, 3, 3, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5,
                                               5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5, 5,
                                               6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6,
                                               6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6,
                                               6, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7,
                                               7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7 };

  uint16_t m_Probability{ uint16_t(One / 2) };
  uint8_t  m_Count{ 0 };
  uint8_t  m_MaximumShift;
};

/** Range encoder appending to a byte vector. */
class DelaunayCompression_EXPORT ArithmeticEncoder
{
public:
  /** Bytes are appended to `out` (which may already hold a header). */
  explicit ArithmeticEncoder(std::vector<uint8_t> & out);

  /** Codes one bit (0 or non-zero) with an adaptive probability, then adapts it. Inline: the bounded-error
   * layer codes one or more a voxel. */
  void
  Encode(BitModel & model, int bit)
  {
    const uint32_t bound = uint32_t((uint64_t(m_Range) * model.GetProbability()) >> BitModel::ProbabilityBits);
    if (bit)
    {
      m_Low += bound;
      m_Range -= bound;
    }
    else
    {
      m_Range = bound;
    }
    model.Update(bit);
    Normalize();
  }

  /** Codes the low `bits` bits of `value` (0 <= bits <= 32), most significant first, each with
   * probability 1/2. */
  void
  EncodeEquiprobable(uint32_t value, int bits);

  /** Flushes the coder state (4 bytes). Nothing may be encoded afterwards. */
  void
  Finish();

  /** Size in bits of the stream so far, flush included (a close estimate before Finish()). */
  double
  GetBitCount() const;

private:
  void
  ShiftLow();
  void
  Normalize()
  {
    while (m_Range < TopValue)
    {
      m_Range <<= 8;
      ShiftLow();
    }
  }

  static constexpr uint32_t TopValue = 1u << 24;

  std::vector<uint8_t> * m_Out; // a pointer, not a reference: a coder of runs works on a copy, then assigns it
  std::size_t            m_Start;
  uint64_t               m_Low{ 0 };
  uint32_t               m_Range{ 0xFFFFFFFFu };
  uint8_t                m_Cache{ 0 };
  uint64_t               m_CacheSize{ 1 };
  bool                   m_First{ true };
  bool                   m_Finished{ false };
};

/** Range decoder reading a byte range it never reads past. */
class DelaunayCompression_EXPORT ArithmeticDecoder
{
public:
  ArithmeticDecoder(const uint8_t * data, std::size_t size);

  /** Inline, as ArithmeticEncoder::Encode. */
  int
  Decode(BitModel & model)
  {
    const uint32_t bound = uint32_t((uint64_t(m_Range) * model.GetProbability()) >> BitModel::ProbabilityBits);
    int            bit;
    if (m_Code < bound)
    {
      m_Range = bound;
      bit = 0;
    }
    else
    {
      m_Code -= bound;
      m_Range -= bound;
      bit = 1;
    }
    model.Update(bit);
    Normalize();
    return bit;
  }

  uint32_t
  DecodeEquiprobable(int bits);

  /** True once the decoder needed a byte beyond the end (it got zeros): the stream is truncated
   * or corrupt, and what was decoded since is garbage. */
  bool
  Overrun() const
  {
    return m_Overrun;
  }

  /** Bytes consumed so far (equal to the encoded size after a complete, correct decode). */
  std::size_t
  GetPosition() const
  {
    return m_Position;
  }

private:
  uint8_t
  NextByte()
  {
    if (m_Position < m_Size)
    {
      return m_Data[m_Position++];
    }
    m_Overrun = true;
    return 0;
  }
  void
  Normalize()
  {
    while (m_Range < TopValue)
    {
      m_Range <<= 8;
      m_Code = (m_Code << 8) | NextByte();
    }
  }

  static constexpr uint32_t TopValue = 1u << 24;

  const uint8_t * m_Data;
  std::size_t     m_Size;
  std::size_t     m_Position{ 0 };
  uint32_t        m_Range{ 0xFFFFFFFFu };
  uint32_t        m_Code{ 0 };
  bool            m_Overrun{ false };
};

/** Adaptive code of an unsigned 32-bit integer, Exp-Golomb style: with e = floor(log2(v + 1)),
 * e in unary (adaptive model per position), then the e bits of v + 1 below its leading one, the
 * first `AdaptiveMantissaBits` of them with adaptive models per (e, position in a binary tree), the
 * rest equiprobable. Small values cost about their entropy once learned; any value costs at most
 * about 2 log2(v + 1) + 1 bits. */
class DelaunayCompression_EXPORT UIntModel
{
public:
  static constexpr int AdaptiveMantissaBits = 2;

  explicit UIntModel(int maximumShift = 5);

  void
  Encode(ArithmeticEncoder & encoder, uint32_t value);
  uint32_t
  Decode(ArithmeticDecoder & decoder);

private:
  std::array<BitModel, 32>                                        m_Prefix;
  std::array<std::array<BitModel, 1 << AdaptiveMantissaBits>, 33> m_Mantissa;
};

/** Adaptive code of a signed 32-bit integer: zero flag, sign, then |v| - 1 with a UIntModel
 * (INT32_MIN included). */
class DelaunayCompression_EXPORT SIntModel
{
public:
  explicit SIntModel(int maximumShift = 5);

  /** The zero flag inline (most residuals of the bounded-error layer are 0), the rest out of line. */
  void
  Encode(ArithmeticEncoder & encoder, int32_t value)
  {
    encoder.Encode(m_Zero, value == 0);
    if (value != 0)
    {
      EncodeNonZero(encoder, value);
    }
  }
  int32_t
  Decode(ArithmeticDecoder & decoder)
  {
    return decoder.Decode(m_Zero) ? 0 : DecodeNonZero(decoder);
  }
  /** The zero flag's model (1: the value is 0), for a coder of runs of zeros that keeps a copy of it in a
   * register while it codes the flags itself, then stores it back. */
  BitModel &
  ZeroFlag()
  {
    return m_Zero;
  }

private:
  void
  EncodeNonZero(ArithmeticEncoder & encoder, int32_t value);
  int32_t
  DecodeNonZero(ArithmeticDecoder & decoder);

  BitModel  m_Zero;
  BitModel  m_Sign;
  UIntModel m_Magnitude;
};

} // namespace dcv

#endif
