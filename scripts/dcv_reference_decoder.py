#!/usr/bin/env python3
# =========================================================================
#
#  Copyright NumFOCUS
#
#  Licensed under the Apache License, Version 2.0 (the "License");
#  you may not use this file except in compliance with the License.
#  You may obtain a copy of the License at
#
#         http://www.apache.org/licenses/LICENSE-2.0.txt
#
#  Unless required by applicable law or agreed to in writing, software
#  distributed under the License is distributed on an "AS IS" BASIS,
#  WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
#  See the License for the specific language governing permissions and
#  limitations under the License.
#
# =========================================================================
"""Reference decoder of .dcv files, written from docs/format.md alone (Python 3, standard library only).

It exists so that the document and the C++ code cannot drift apart: the test
dcvFormatSpecificationTest runs it on files the C++ encoder makes and compares its output with what the
C++ decoder gives. Each part below implements one section of docs/format.md, in the document's order, and
says which; where this script and the C++ sources disagree, the document decides.

Usage:
    dcv_reference_decoder.py FILE.dcv [--neighbours NEIGHBOURS.txt]

Prints the header fields, one per line ("name value ..."; floats as Python's repr, which reads back
exactly; one "metadata KEY VALUE" line per pair, both as JSON strings; the "DICOM Header" value, which is
bytes, as its mode and counts), then one line "x y z" per point in decoding order.

Values: a value depends on the vertex's Delaunay neighbours under CGAL's symbolic perturbation
(section "Tetrahedralization"), which a standard-library script cannot build efficiently. So this script
decodes the container and the positions on its own, and decodes the values only when it is given the
neighbour relation with --neighbours: a text file with one line per vertex, in position order, listing the
indices of that vertex's neighbours (separated by white space, any order). The point lines are then
"x y z value". Without it, the values part of the payload is not read (so a stream truncated inside the
values is only detected with --neighbours).

Exit status: 0 on success; 1, with a message "FILE: problem" on stderr, when the file is damaged or
truncated (CRC-32 mismatch, a field out of range, a stream overrun, ...); 2 on a usage error.
"""

import argparse
import json
import math
import struct
import sys
import zlib


class DamagedFile(Exception):
    """The file breaks a rule of docs/format.md (the message says which)."""


# =========================================================================
# Container (section "Container")
# =========================================================================

MAGIC = b"\x89DCV"
VERSION = 1
PIXEL_TYPES = {1: "uint8", 2: "int8", 3: "uint16", 4: "int16", 5: "uint32", 6: "int32", 7: "float32", 8: "float64"}
MODES = {0: "silva", 1: "dec", 2: "dec+com", 3: "best", 4: "bounded-error"}
FLAG_DIRECTION = 1
FLAG_METADATA = 2
FLAG_SCALE = 4
FLAG_RESIDUAL = 8
FLAG_DEFLATED = 16
FLAG_INTER_SLICE = 32
FLAG_AXIS_DIRECTION = 64
FLAG_FORM = 128
FORM_CONSTANT = 1  # no points: the spline is the constant q0
FORM_UNIT_STEP = 2  # the residual step is 1, not stored
FORM_COMPACT = 4  # the residual layer's codestream is stored compact
FORM_VIDEO = 8  # the residual layer is a video stream (the video layer): HEVC, or with FORM_AV1 AV1
FORM_AV1 = 16
FORM_BOUNDED = 32  # the residual layer is a bounded-error layer
# Section "Header", direction code: row r is +-1 at column AXIS_PERMUTATIONS[code & 7][r].
AXIS_PERMUTATIONS = ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0))
# Section "Inter-slice wavelet": band weights in 1/4096 (low band after l levels, high band of level k).
LOW_BAND_WEIGHT = (5917, 8012, 11201, 15795, 22321, 31560)
HIGH_BAND_WEIGHT = (4096, 4639, 6084, 8428, 11856, 16744)
MAXIMUM_INFLATED_METADATA = 16 << 20
DICOM_HEADER_KEY = "DICOM Header"


def split_dicom_header(value):
    """Section "DICOM header": version 1, mode, N files, the common part, then each file's part, each a
    uint32 length and that many bytes of DICOM data elements (explicit VR little endian), nothing after.
    Returns (mode, common, [part of each file]); the elements are not parsed here."""
    f = _Fields(value, 0, len(value))
    version, mode, files = f.unpack("BBI", "DICOM header")
    if version != 1:
        raise DamagedFile("DICOM header block of unknown version %d" % version)
    if mode > 1 or files < 1 or files > 65535 or files > f.left() // 4:
        raise DamagedFile("inconsistent DICOM header block")
    parts = []
    for _ in range(files + 1):
        (length,) = f.unpack("I", "DICOM header")
        parts.append(f.take(length, "DICOM header"))
    if f.left() != 0:
        raise DamagedFile("inconsistent DICOM header block")
    return mode, parts[0], parts[1:]
IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


class _Fields:
    """Little-endian fields read in order from data[position:end]; refuses to read past end."""

    def __init__(self, data, position, end):
        self.data, self.position, self.end = data, position, end

    def take(self, count, what):
        if self.end - self.position < count:
            raise DamagedFile("truncated (the file ends inside the %s)" % what)
        chunk = self.data[self.position:self.position + count]
        self.position += count
        return chunk

    def unpack(self, fmt, what):
        return struct.unpack("<" + fmt, self.take(struct.calcsize("<" + fmt), what))

    def left(self):
        return self.end - self.position


# Section "Compact residual layer": the 9/7 steps of OpenJPEG's QCD, for its level index 0 (finest) to 5:
# (p, mantissa) of LL, of HL and LH, of HH; SPqcd = ((precision - p) << 11) | mantissa.
QCD_STEPS = [[(0, 0), (-2, 2003), (-2, 1890)], [(-1, 36), (-2, 5), (-2, 71)], [(-3, 1874), (-4, 1872), (-4, 1896)],
             [(-4, 1848), (-5, 1792), (-5, 1760)], [(-5, 1824), (-6, 1776), (-6, 1728)], [(-6, 1824), None, None]]


def implicit_qcd(precision, levels, reversible):
    bands = 3 * levels + 1
    out = struct.pack(">HHB", 0xFF5C, 3 + bands * (1 if reversible else 2), 0x40 if reversible else 0x42)
    for b in range(bands):
        resolution = 0 if b == 0 else (b - 1) // 3 + 1
        orientation = 0 if b == 0 else (b - 1) % 3 + 1  # LL, HL, LH, HH
        kind = 0 if orientation == 0 else 2 if orientation == 3 else 1
        if reversible:
            out += bytes([(precision + (0, 1, 2)[kind]) << 3])
        else:
            p, mantissa = QCD_STEPS[levels - resolution][kind]
            out += struct.pack(">H", ((precision - p) << 11) | mantissa)
    return out


def expand_layer(stored, size):
    """Section "Compact residual layer": the JPEG 2000 codestream a compact layer stands for."""
    sx, sy, sz = size
    damaged = DamagedFile("damaged residual layer (invalid compact fields)")
    if len(stored) < 4:
        raise damaged
    columns, packed, levels = struct.unpack_from(">HBB", stored, 0)
    precision, implicit, reversible = (packed & 0x3F) + 1, packed & 0x40, packed >> 7
    if precision > 38 or levels > 32 or columns > sz or (columns == 0 and sz > 16384):
        raise damaged
    if implicit and (levels > 5 or precision > (29 if reversible else 25)):
        raise damaged
    if columns == 0:
        components, width, height = sz, sx, sy
    else:
        components, width, height = 1, columns * sx, -(-sz // columns) * sy
    if width > 0xFFFFFFFF or height > 0xFFFFFFFF:
        raise damaged
    if implicit:
        qcd, data = implicit_qcd(precision, levels, reversible), stored[4:]
    else:
        if len(stored) < 8:
            raise damaged
        (marker, lqcd) = struct.unpack_from(">HH", stored, 4)
        if marker != 0xFF5C or lqcd < 3 or 4 + 2 + lqcd > len(stored):
            raise damaged
        qcd, data = stored[4:6 + lqcd], stored[6 + lqcd:]
    siz = struct.pack(">HHHIIIIIIIIH", 0xFF51, 38 + 3 * components, 0, width, height, 0, 0, width, height, 0, 0,
                      components) + bytes([0x80 | (precision - 1), 1, 1]) * components
    cod = struct.pack(">HHBBHBBBBBB", 0xFF52, 12, 0, 0, 1, 0, levels, 4, 4, 0, reversible)
    sot = struct.pack(">HHHIBB", 0xFF90, 10, 0, 14 + len(data), 0, 1)
    return b"\xff\x4f" + siz + cod + qcd + sot + b"\xff\x93" + data + b"\xff\xd9"


def parse_container(data):
    """Checks, in the document's order, magic, version, CRC-32, then every field's range; returns a dict."""
    if len(data) < 4 or data[:4] != MAGIC:
        raise DamagedFile("not a .dcv file (wrong magic bytes)")
    if len(data) < 5:
        raise DamagedFile("truncated (the file ends inside the header)")
    if data[4] != VERSION:
        raise DamagedFile(".dcv version %d is not supported (this reader knows %d)" % (data[4], VERSION))
    if len(data) < 9:
        raise DamagedFile("truncated (the file ends inside the header)")
    # CRC-32 (zlib's crc32) of every byte before the last 4: checked before any other number is used.
    body = len(data) - 4
    (stored,) = struct.unpack_from("<I", data, body)
    if zlib.crc32(data[:body]) & 0xFFFFFFFF != stored:
        raise DamagedFile("damaged or truncated (CRC-32 mismatch)")

    f = _Fields(data, 5, body)
    pixel_type, flags, mode = f.unpack("3B", "header")
    if pixel_type not in PIXEL_TYPES:
        raise DamagedFile("unknown pixel type code %d" % pixel_type)
    if (flags & FLAG_DEFLATED and not flags & FLAG_METADATA) or \
            (flags & FLAG_INTER_SLICE and not flags & FLAG_RESIDUAL) or \
            (flags & FLAG_AXIS_DIRECTION and not flags & FLAG_DIRECTION) or \
            (flags & FLAG_FORM and not flags & FLAG_RESIDUAL):
        raise DamagedFile("unknown header flags %d" % flags)
    size = f.unpack("3H", "header")
    if min(size) < 2:
        raise DamagedFile("absurd volume size %dx%dx%d (each axis needs at least 2 voxels)" % size)
    spacing = f.unpack("3d", "header")
    origin = f.unpack("3d", "header")
    if flags & FLAG_AXIS_DIRECTION:
        (code,) = f.unpack("B", "header")
        if code & 7 > 5 or code > 63:
            raise DamagedFile("invalid direction code %d" % code)
        direction = [0.0] * 9
        for row in range(3):
            direction[3 * row + AXIS_PERMUTATIONS[code & 7][row]] = -1.0 if code & (8 << row) else 1.0
        direction = tuple(direction)
    else:
        direction = f.unpack("9d", "header") if flags & FLAG_DIRECTION else IDENTITY
    scale = f.unpack("3B", "header") if flags & FLAG_SCALE else (1, 1, 1)
    if not all(1 <= s <= 16 for s in scale):
        raise DamagedFile("invalid Delaunay scale")
    if not all(math.isfinite(s) and s > 0.0 for s in spacing):
        raise DamagedFile("invalid voxel spacing")
    form = 0
    if flags & FLAG_FORM:
        (form,) = f.unpack("B", "header")
        if form & ~(FORM_CONSTANT | FORM_UNIT_STEP | FORM_COMPACT | FORM_VIDEO | FORM_AV1 | FORM_BOUNDED):
            raise DamagedFile("unknown form bits %d" % form)
        if form & FORM_AV1 and not form & FORM_VIDEO:
            raise DamagedFile("form bit 4 (AV1) without a video layer (form bit 3)")
        if form & FORM_VIDEO and (not form & FORM_CONSTANT or form & FORM_COMPACT or flags & FLAG_INTER_SLICE):
            raise DamagedFile("a video layer (form bit 3) needs a constant spline (form bit 0), no compact form "
                              "and no inter-slice wavelet")
        if form & FORM_BOUNDED and (not form & FORM_CONSTANT or form & (FORM_COMPACT | FORM_VIDEO | FORM_AV1) or
                                    flags & FLAG_INTER_SLICE):
            raise DamagedFile("a bounded-error layer (form bit 5) needs a constant spline (form bit 0), no compact "
                              "form, no video layer and no inter-slice wavelet")
    if form & FORM_CONSTANT:
        (q0,) = f.unpack("d", "header")
        if not math.isfinite(q0):
            raise DamagedFile("invalid value quantization")
        q, n, payload = 1.0, 8, b""
    else:
        q0, q = f.unpack("2d", "header")
        if not (math.isfinite(q0) and math.isfinite(q) and q > 0.0):
            raise DamagedFile("invalid value quantization")
        voxels = size[0] * size[1] * size[2]
        n, length = f.unpack("2I", "header")
        if not 8 <= n <= voxels:
            raise DamagedFile("absurd point count %d for %d voxels" % (n, voxels))
        if length > f.left():
            raise DamagedFile("truncated (the payload is %d bytes, %d remain)" % (length, f.left()))
        if n > 11728 * length:  # every value costs at least 6.825e-4 bits (docs/format.md, "Resource limits")
            raise DamagedFile("damaged (%d points cannot be coded in %d payload bytes, at most %d)"
                              % (n, length, 11728 * length))
        payload = f.take(length, "payload")

    residual_step, residual_levels, residual_layer = 0.0, 0, b""
    if flags & FLAG_RESIDUAL:
        (residual_step,) = (1.0,) if form & FORM_UNIT_STEP else f.unpack("d", "residual layer")
        if not (math.isfinite(residual_step) and residual_step > 0.0):
            raise DamagedFile("invalid residual step")
        if flags & FLAG_INTER_SLICE:
            (residual_levels,) = f.unpack("B", "residual layer")
            most = inter_slice_levels(size[2])
            if not 1 <= residual_levels <= most:
                raise DamagedFile("invalid inter-slice wavelet (%d levels; %d slices take 1 to %d)"
                                  % (residual_levels, size[2], most))
        (residual_length,) = f.unpack("I", "residual layer")
        if residual_length == 0 or residual_length > f.left():
            raise DamagedFile("truncated (the residual layer is %d bytes, %d remain)" % (residual_length, f.left()))
        residual_layer = f.take(residual_length, "residual layer")
        if form & FORM_COMPACT:
            residual_layer = expand_layer(residual_layer, size)

    metadata = []
    if flags & FLAG_METADATA:
        count, block_size = f.unpack("2I", "metadata")
        if block_size != f.left():
            raise DamagedFile("inconsistent metadata block")
        if flags & FLAG_DEFLATED:
            (inflated_size,) = f.unpack("I", "metadata")
            if inflated_size > MAXIMUM_INFLATED_METADATA:
                raise DamagedFile("absurd metadata size %d" % inflated_size)
            stream = f.take(f.left(), "metadata")
            try:
                inflater = zlib.decompressobj()
                pairs = inflater.decompress(stream, inflated_size + 1)
                if len(pairs) != inflated_size or not inflater.eof or inflater.unused_data:
                    raise zlib.error("size")
            except zlib.error:
                raise DamagedFile("damaged metadata block")
        else:
            pairs = f.take(block_size, "metadata")
        m = _Fields(pairs, 0, len(pairs))
        if count > len(pairs) // 8:
            raise DamagedFile("inconsistent metadata block")
        for _ in range(count):
            pair = []
            for _ in range(2):
                (text_length,) = m.unpack("I", "metadata")
                pair.append(m.take(text_length, "metadata"))
            key = pair[0].decode("utf-8", errors="replace")
            if key == DICOM_HEADER_KEY:
                if any(k == DICOM_HEADER_KEY for k, _ in metadata):
                    raise DamagedFile("two DICOM header blocks")
                # Bytes, not text (section "DICOM header"): checked, shown by its counts.
                metadata.append((key, split_dicom_header(pair[1])))
            else:
                # UTF-8 by the document; shown with replacement characters if not (it is not checked).
                metadata.append((key, pair[1].decode("utf-8", errors="replace")))
        if m.left() != 0:
            raise DamagedFile("inconsistent metadata block")
    if f.left() != 0:
        raise DamagedFile("%d unexpected bytes before the checksum" % f.left())

    return dict(version=VERSION, pixel_type=pixel_type, flags=flags, mode=mode, size=size, spacing=spacing,
                origin=origin, direction=direction, scale=scale, q0=q0, q=q, n=n, payload=payload, metadata=metadata, form=form,
                residual_step=residual_step, residual_levels=residual_levels, residual_layer=residual_layer)


# =========================================================================
# Payload: arithmetic decoder (section "Arithmetic decoder")
# =========================================================================

class ArithmeticDecoder:
    """LZMA-style range decoder over the payload; past its end it reads zeros and notes the overrun."""

    def __init__(self, payload):
        self.payload, self.position, self.overrun = payload, 0, False
        self.range = 0xFFFFFFFF
        self.code = 0
        for _ in range(4):  # the first 4 bytes, big-endian
            self.code = ((self.code << 8) | self.next_byte()) & 0xFFFFFFFF

    def next_byte(self):
        if self.position < len(self.payload):
            byte = self.payload[self.position]
            self.position += 1
            return byte
        self.overrun = True
        return 0

    def renormalize(self):
        while self.range < (1 << 24):
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.code = ((self.code << 8) | self.next_byte()) & 0xFFFFFFFF

    def decode_bit(self, model):
        bound = (self.range * model.p) >> 16
        if self.code < bound:
            self.range = bound
            bit = 0
        else:
            self.code -= bound
            self.range -= bound
            bit = 1
        model.update(bit)
        self.renormalize()
        return bit

    def decode_equiprobable(self, bits):
        v = 0
        for _ in range(bits):  # the most significant bit first
            self.range >>= 1
            if self.code >= self.range:
                self.code -= self.range
                v = 2 * v + 1
            else:
                v = 2 * v
            self.renormalize()
        return v


# =========================================================================
# Adaptive bit model (section "Adaptive bit model")
# =========================================================================

# T[count]: the adaptation shift before the cap S, round(log2(count + 2)).
SHIFT = [1] + [2] * 3 + [3] * 6 + [4] * 11 + [5] * 23 + [6] * 45 + [7] * 39
assert len(SHIFT) == 128


class BitModel:
    """p = P(bit = 0) * 2^16; fresh: p = 32768, count = 0; with a prior: the given p, count = 16."""

    __slots__ = ("p", "count", "max_shift")

    def __init__(self, max_shift, prior=None):
        self.max_shift = max_shift
        self.p, self.count = (32768, 0) if prior is None else (prior, 16)

    def update(self, bit):
        s = min(SHIFT[self.count], self.max_shift)
        if self.count < 127:
            self.count += 1
        if bit == 1:
            self.p -= self.p >> s
        else:
            self.p += (65536 - self.p) >> s


# =========================================================================
# Integers (section "Integers")
# =========================================================================

class UIntModel:
    """Exp-Golomb binarization of v + 1: prefix[0..31], mantissa[e][1..3] (index 0 unused)."""

    def __init__(self, max_shift):
        self.prefix = [BitModel(max_shift) for _ in range(32)]
        self.mantissa = [[BitModel(max_shift) for _ in range(4)] for _ in range(33)]

    def decode(self, d):
        e = 0
        while e < 32 and d.decode_bit(self.prefix[e]) == 1:
            e += 1
        if e == 32:
            return 2 ** 32 - 1
        w, node = 1, 1
        for t in range(e):
            if t < 2:
                b = d.decode_bit(self.mantissa[e][node])
                node = 2 * node + b
                w = 2 * w + b
            else:
                w = (w << (e - t)) | d.decode_equiprobable(e - t)
                break
        return w - 1


class SIntModel:
    """zero, sign and a UInt magnitude; returns a 32-bit two's-complement integer."""

    def __init__(self, max_shift):
        self.zero, self.sign = BitModel(max_shift), BitModel(max_shift)
        self.magnitude = UIntModel(max_shift)

    def decode(self, d):
        if d.decode_bit(self.zero) == 1:
            return 0
        negative = d.decode_bit(self.sign)
        m = (self.magnitude.decode(d) + 1) % 2 ** 32
        u = (2 ** 32 - m) % 2 ** 32 if negative else m
        return u - 2 ** 32 if u >= 2 ** 31 else u


# =========================================================================
# Positions (section "Positions")
# =========================================================================

# U(n, i) for n = 1..16, i = 0..floor(n/2)-1: the priors of unary[n][d][i].
UNARY_PRIORS = {
    1: [], 2: [32768], 3: [49152], 4: [57344, 28087], 5: [61440, 43691], 6: [63488, 52852, 26214],
    7: [64512, 58254, 40960], 8: [65024, 61408, 50116, 25206], 9: [65280, 63223, 55945, 39322],
    10: [65408, 64253, 59650, 48290, 24576], 11: [65472, 64831, 61974, 54237, 38229],
    12: [65504, 65152, 63411, 58214, 46988, 24145], 13: [65520, 65328, 64284, 60855, 52933, 37449],
    14: [65528, 65424, 64807, 62586, 57041, 46015, 23831], 15: [65532, 65476, 65116, 63702, 59877, 51910, 36864],
    16: [65534, 65504, 65296, 64411, 61817, 56073, 45260, 23593],
}
# Priors of side[0][c] for c = 1..7.
SIDE_PRIORS = [65535, 43691, 39322, 37449, 36409, 35747, 35289]


class PositionModels:
    """The models of the positions, created once for the whole payload, all with maximum shift 7."""

    def __init__(self):
        self.unary = {n: [[BitModel(7, UNARY_PRIORS[n][i]) for i in range(n // 2)] for _ in range(24)]
                      for n in range(1, 17)}
        self.side = [[BitModel(7) for _ in range(9)] for _ in range(3)]
        for c in range(1, 8):
            self.side[0][c] = BitModel(7, SIDE_PRIORS[c - 1])
        self.zero = [BitModel(7) for _ in range(34)]
        self.sign = [BitModel(7) for _ in range(34)]
        self.magnitude = [UIntModel(7) for _ in range(34)]


def decode_positions(d, size, n):
    """The n points (x, y, z) of the kd-tree of the grid box, in decoding order."""
    models = PositionModels()
    points = []

    def decode_small(n, V, L, lo, hi):
        def feasible(v):
            return lo <= v <= hi
        density = min((V // n).bit_length() - 1, 23)
        candidates = [i for i in range(n // 2 + 1) if feasible(i) or feasible(n - i)]
        m = candidates[-1]
        for i in candidates[:-1]:
            if d.decode_bit(models.unary[n][density][i]) == 1:
                m = i
                break
        if 2 * m == n:
            return m
        if feasible(m) and feasible(n - m):
            c = min((L + 1) // 2, 8) if L % 2 == 1 else 0
            r = 0 if n == 1 else (1 if m == 0 else 2)
            upper = d.decode_bit(models.side[r][c])
        else:
            upper = 0 if feasible(m) else 1
        return n - m if upper == 1 else m

    def decode_large(n, L, lo, hi):
        x = min(max((n * (L // 2) + L // 2) // L, lo), hi)
        c = min(n.bit_length() // 2, 33)
        if d.decode_bit(models.zero[c]) == 1:
            return x
        negative = d.decode_bit(models.sign[c])
        magnitude = models.magnitude[c].decode(d) + 1
        step = min(magnitude, x - lo if negative else hi - x)
        return x - step if negative else x + step

    def decode_split(n, V, V1, L):
        V2 = V - V1
        complement = 2 * n > V
        if complement:
            n = V - n
        lo, hi = max(0, n - V2), min(n, V1)
        k = decode_small(n, V, L, lo, hi) if n <= 16 else decode_large(n, L, lo, hi)
        return V1 - k if complement else k

    def decode_box(lo, hi, n):
        extent = [hi[a] - lo[a] for a in range(3)]
        V = extent[0] * extent[1] * extent[2]
        if n == 0:
            return
        if n == V:
            for z in range(lo[2], hi[2]):
                for y in range(lo[1], hi[1]):
                    for x in range(lo[0], hi[0]):
                        points.append((x, y, z))
            return
        a = extent.index(max(extent))  # the first of x, y, z on ties
        L = extent[a]
        mid = lo[a] + L // 2
        V1 = (V // L) * (L // 2)
        k = decode_split(n, V, V1, L)
        first_hi = list(hi)
        first_hi[a] = mid
        second_lo = list(lo)
        second_lo[a] = mid
        decode_box(lo, first_hi, k)  # depth first (the recursion is at most ~48 deep)
        decode_box(second_lo, hi, n - k)

    decode_box([0, 0, 0], list(size), n)
    return points


def check_positions(d, size, points):
    """The checks after the positions: the 8 corners of the grid are there, the stream is not overrun."""
    sx, sy, sz = size
    present = set(points)
    for corner in [(x, y, z) for z in (0, sz - 1) for y in (0, sy - 1) for x in (0, sx - 1)]:
        if corner not in present:
            raise DamagedFile("damaged point positions (the corner %d %d %d is missing)" % corner)
    if d.overrun:
        raise DamagedFile("the payload ends inside the point positions")


# =========================================================================
# Values (section "Values"; the neighbours of section "Tetrahedralization" are given)
# =========================================================================

def decode_values(d, neighbours, q0, q):
    """The values q0 + k q of the vertices 0 .. n-1, given each vertex's neighbour indices."""
    residual = [SIntModel(5) for _ in range(4)]
    k = []
    values = []
    for i, around in enumerate(neighbours):
        known = [j for j in around if j < i]
        if not known:
            prediction = k[i - 1] if i > 0 else 0
        else:
            s, c = sum(k[j] for j in known), len(known)
            prediction = (2 * s + c) // (2 * c)  # floor: the mean rounded half up
        context = 0 if not known else 1 if len(known) <= 2 else 2 if len(known) <= 5 else 3
        ki = prediction + residual[context].decode(d)
        if abs(ki) >= 2 ** 31:
            raise DamagedFile("damaged values")
        k.append(ki)
        values.append(q0 + float(ki) * q)  # IEEE double: the product, then the sum
    if d.overrun:
        raise DamagedFile("the payload ends inside the values")
    return values


def read_neighbours(path, n):
    """One line per vertex, in position order: the indices of its neighbours."""
    with open(path, encoding="ascii") as f:
        lines = f.read().splitlines()
    if len(lines) != n:
        raise ValueError("%d lines for %d points" % (len(lines), n))
    neighbours = [[int(token) for token in line.split()] for line in lines]
    for i, around in enumerate(neighbours):
        if any(not 0 <= j < n or j == i for j in around):
            raise ValueError("line %d lists an invalid neighbour index" % (i + 1))
    return neighbours


# =========================================================================
# Bounded-error layer (section "Bounded-error layer"; its streams use the arithmetic decoder and the signed
# integers of the payload's sections above)
# =========================================================================

BOUNDED_HEADER = "diIII"  # E (float64), m (int32), d (uint32), S (uint32), n (uint32)
BOUNDED_ERROR_CAP = 1 << 28  # errors are kept capped at 2^28
BOUNDED_BIAS_RESET = 256  # a bias context's sum and count halve when the count reaches it


def bounded_layer_slab_slices(size):
    """The slices of a slab: max(8, floor(2^22 / (size x size y))), at most size z."""
    sx, sy, sz = size
    return min(max(8, (1 << 22) // (sx * sy)), sz)


def read_bounded_layer(layer, size):
    """The fields of a bounded-error layer and its slabs' streams: (E, m, d, S, n, [stream of each slab]).
    Every field and every slab length is checked before anything is decoded."""
    if len(layer) < struct.calcsize("<" + BOUNDED_HEADER):
        raise DamagedFile("damaged bounded-error layer (%d bytes)" % len(layer))
    f = _Fields(layer, 0, len(layer))
    bound, minimum, span, slab_slices, near = f.unpack(BOUNDED_HEADER, "bounded-error layer")
    if not (math.isfinite(bound) and bound >= 0.0):
        raise DamagedFile("damaged bounded-error layer (its bound is not a finite non-negative number)")
    if minimum + span > 2 ** 31 - 1:
        raise DamagedFile("damaged bounded-error layer (samples beyond 32 bits)")
    if slab_slices != bounded_layer_slab_slices(size):
        raise DamagedFile("damaged bounded-error layer (slabs of %d slices, not %d)"
                          % (slab_slices, bounded_layer_slab_slices(size)))
    slabs = -(-size[2] // slab_slices)
    streams = []
    for s in range(slabs):
        if f.left() < 4:
            raise DamagedFile("the bounded-error layer ends before slab %d of %d" % (s + 1, slabs))
        (length,) = f.unpack("I", "bounded-error layer")
        if f.left() < length:
            raise DamagedFile("the bounded-error layer ends inside slab %d of %d" % (s + 1, slabs))
        streams.append(f.take(length, "bounded-error layer"))
    if f.left() != 0:
        raise DamagedFile("%d bytes follow the bounded-error layer" % f.left())
    return bound, minimum, span, slab_slices, near, streams


def activity_bucket(a, buckets):
    """a for a < 4, else min(C - 1, 2 f + bit f - 1 of a) with f = floor(log2 a)."""
    if a < 4:
        return a
    f = a.bit_length() - 1
    return min(buckets - 1, 2 * f + ((a >> (f - 1)) & 1))


def decode_bounded_slab(d, sx, sy, slices, span, near):
    """The values v = r - m of one slab's slices (grid order, x fastest), decoded from its stream alone."""
    plane = sx * sy
    top = span  # d: values are in [0, d]
    step = 2 * near + 1  # the residual's quantization step
    steps = (span + 2 * near) // step + 1  # M: the residual's modulus, in steps
    half = steps // 2  # H
    cap = BOUNDED_ERROR_CAP
    models = [SIntModel(6) for _ in range(7 * 32)]  # one per coding context 32 class + bucket(a, 32)
    bias_sum = [0] * 128  # per bias context bucket(a, 16) 8 + t
    bias_count = [0] * 128
    # The error planes e_1 .. e_7 and e_f (index 7) of two slices: slice z writes the planes of parity z & 1
    # and reads those of slice z - 1 in the others; they start at 0 in each slab. The first voxel of a slice
    # has no in-slice neighbour: its in-slice error terms are 0.
    planes = [[[0] * plane for _ in range(8)] for _ in range(2)]
    values = [0] * (slices * plane)
    for z in range(slices):
        current, previous = planes[z & 1], planes[(z + 1) & 1]
        has_previous = z > 0
        count = 7 if has_previous else 4
        ef, pf = current[7], previous[7]
        base = z * plane
        below = base - plane  # the start of slice z - 1
        for y in range(sy):
            row = y * sx
            for x in range(sx):
                j = row + x
                # In-slice neighbours (offsets in the slice): n, then w, nw, ne, each n's where it is missing.
                jn = j - sx if y > 0 else (j - 1 if x > 0 else j)
                jw = j - 1 if x > 0 else jn
                jnw = j - sx - 1 if x > 0 and y > 0 else jn
                jne = j - sx + 1 if y > 0 and x + 1 < sx else jn
                first = jn == j
                if first:  # the first voxel of a slice: all four are (x, y, z - 1), or 0
                    vw = vn = vnw = vne = values[below + j] if has_previous else 0
                else:
                    vw, vn, vnw, vne = values[base + jw], values[base + jn], values[base + jnw], values[base + jne]
                p = [vw + vn - vnw, vw + vne - vn, vn, vw]
                if has_previous:
                    vp = values[below + j]
                    dw, dn = vw - values[below + jw], vn - values[below + jn]
                    dnw, dne = vnw - values[below + jnw], vne - values[below + jne]
                    p.append(vp + dw + dn - dnw)
                    p.append(vp + (dw + dn + dne + dnw + 2) // 4)
                    p.append(vp)
                # Each predictor clamped to [0, d], weighted by the inverse square of its recent errors.
                weight_sum = weighted = 0
                for k in range(count):
                    pk = p[k]
                    if pk < 0:
                        pk = p[k] = 0
                    elif pk > top:
                        pk = p[k] = top
                    e = current[k]
                    s = 0 if first else e[jw] + e[jn] + ((e[jnw] + e[jne]) >> 1)
                    if has_previous:
                        s += previous[k][j]
                    # i_k = floor(2^30 / x'), x' = s_k + 1 with the bits below its 8 leading ones cleared.
                    s += 1
                    if s < 256:
                        inverse = (1 << 30) // s
                    else:
                        shift = s.bit_length() - 8
                        inverse = ((1 << 30) // (s >> shift)) >> shift
                    weight = max(1, (inverse * inverse) >> 38)
                    weight_sum += weight
                    weighted += weight * pk
                blend = (weighted + weight_sum // 2) // weight_sum
                if first:
                    activity = (pf[j] if has_previous else 0) + ((max(p) - min(p)) >> 1)
                else:
                    activity = ef[jw] + ef[jn] + ((ef[jnw] + ef[jne]) >> 1) + (pf[j] if has_previous else ef[jw]) + \
                        ((max(p) - min(p)) >> 1)
                texture = (vw > blend) + 2 * (vn > blend) + (4 * (p[6] > blend) if has_previous else 0)
                b = activity_bucket(activity, 16) * 8 + texture
                c = bias_count[b]
                correction = (2 * bias_sum[b] + c) // (2 * c) if c > 0 else 0
                prediction = blend + correction
                prediction = 0 if prediction < 0 else (top if prediction > top else prediction)
                # The residual, folded into [-H, M - H - 1]: the sum wraps back into [0, d].
                # The end class: the prediction at, near or fairly near the low (1-3) or high (4-6) end.
                low, high = prediction, top - prediction
                nearest, side = (low, 0) if low <= high else (high, 3)
                if nearest == 0:
                    end = 1 + side
                elif 4 * nearest < activity + 4:
                    end = 2 + side
                elif nearest < activity + 1:
                    end = 3 + side
                else:
                    end = 0
                # The residual in steps of 2 n + 1, folded into [-H, M - H - 1]: the sum wraps back.
                q = models[32 * end + activity_bucket(activity, 32)].decode(d)
                if q < -half or q >= steps - half:
                    raise DamagedFile("damaged bounded-error layer (a sample outside its range)")
                residual = q * step
                v = prediction + residual
                if v < -near:
                    v += steps * step
                elif v > top + near:
                    v -= steps * step
                v = 0 if v < 0 else (top if v > top else v)
                values[base + j] = v
                bias_sum[b] += residual
                c += 1
                if c == BOUNDED_BIAS_RESET:
                    bias_sum[b] //= 2
                    c = BOUNDED_BIAS_RESET // 2
                bias_count[b] = c
                for k in range(count):
                    current[k][j] = min(abs(v - p[k]), cap)
                for k in range(count, 7):  # a slab's first slice: predictors 5 to 7 take predictor 1's error
                    current[k][j] = current[0][j]
                ef[j] = min(abs(residual), cap)
            if d.overrun:  # checked at every row's end, as the library does
                raise DamagedFile("the bounded-error layer ends inside a slab")
    return values


def decode_bounded_layer(h):
    """Section "Bounded-error layer": the samples r in grid order (x fastest), each slab decoded alone, each
    stream read to its last byte and never past it."""
    sx, sy, sz = h["size"]
    _, minimum, span, slab_slices, near, streams = read_bounded_layer(h["residual_layer"], h["size"])
    samples = []
    for s, stream in enumerate(streams):
        d = ArithmeticDecoder(stream)
        slices = min(slab_slices, sz - s * slab_slices)
        values = decode_bounded_slab(d, sx, sy, slices, span, near)
        if d.position != len(stream):
            raise DamagedFile("damaged bounded-error layer (%d bytes follow slab %d)"
                              % (len(stream) - d.position, s + 1))
        samples.extend(v + minimum for v in values)
    return samples


# =========================================================================
# Command line
# =========================================================================

def read_pgx(data):
    """(width, height, samples) of a PGX file: "PG ML|LM +|- depth width height\\n", then the samples,
    1, 2 or 4 bytes each."""
    end = data.index(b"\n")
    fields = data[:end].decode("ascii").split()
    endian = ">" if fields[1] == "ML" else "<"
    signed, depth = fields[2] == "-", int(fields[3])
    width, height = int(fields[4]), int(fields[5])
    nbytes = 1 if depth <= 8 else 2 if depth <= 16 else 4
    code = {1: "b", 2: "h", 4: "i"}[nbytes]
    return width, height, struct.unpack_from(endian + str(width * height) + (code if signed else code.upper()),
                                             data, end + 1)


def inter_slice_levels(slices):
    """Section "Inter-slice wavelet", Levels: every level's input holds two slices or more, at most 6."""
    levels = 0
    while levels < 6 and -(-slices // (1 << levels)) >= 2:
        levels += 1
    return levels


def inverse_inter_slice(samples, size, levels):
    """Section "Inter-slice wavelet", Inverse: each column along z unweighted, then the 5/3 lifting undone."""
    sx, sy, sz = size
    plane = sx * sy
    n = [-(-sz // (1 << k)) for k in range(levels + 1)]  # n_k = ceil(size z / 2^k)
    weights = []
    for i in range(sz):
        if i < n[levels]:
            weights.append(LOW_BAND_WEIGHT[levels - 1])
        else:
            k = min(k for k in range(1, levels + 1) if i >= n[k])  # n_k <= i < n_(k-1)
            weights.append(HIGH_BAND_WEIGHT[k - 1])
    out = list(samples)
    for c in range(plane):
        col = [(8192 * samples[z * plane + c] + w) // (2 * w) for z, w in zip(range(sz), weights)]
        for k in range(levels, 0, -1):
            m = n[k - 1]
            lows, highs = (m + 1) // 2, m // 2
            low, high = col[:lows], col[lows:m]
            x = [0] * m
            for i in range(lows):  # D(-1) = D(0); for odd m, D((m-1)/2) = D((m-3)/2)
                x[2 * i] = low[i] - ((high[max(i - 1, 0)] + high[min(i, highs - 1)] + 2) >> 2)
            for i in range(highs):  # X(m) = X(m-2)
                right = x[2 * i + 2] if 2 * i + 2 < m else x[2 * i]
                x[2 * i + 1] = high[i] + ((x[2 * i] + right) >> 1)
            col[:m] = x
        for z in range(sz):
            out[z * plane + c] = min(max(col[z], -(2 ** 31) + 1), 2 ** 31 - 1)
    return out


def decode_video_layer(h):
    """Section "Video layer": the samples r in grid order (x fastest), decoded by libde265's dec265
    (libde265-examples) from the HEVC stream: picture z's top-left size x by size y samples are slice z."""
    import os
    import re
    import shutil
    import subprocess
    import tempfile
    tool = shutil.which("libde265-dec265") or shutil.which("dec265")
    if tool is None:
        raise DamagedFile("dec265 (libde265-examples) is needed to decode the video layer")
    sx, sy, sz = h["size"]
    work = tempfile.mkdtemp(prefix="dcv-video-")
    try:
        stream, yuv = os.path.join(work, "layer.hevc"), os.path.join(work, "layer.yuv")
        with open(stream, "wb") as out:
            out.write(h["residual_layer"])
        run = subprocess.run([tool, "-q", "-d", "-o", yuv, stream], capture_output=True, text=True)
        fields = dict(re.findall(r"\b(pic_width_in_luma_samples|pic_height_in_luma_samples|bit_depth_luma|"
                                 r"chroma_format_idc)\s*:\s*(\d+)", run.stdout + run.stderr))
        if run.returncode != 0 or len(fields) < 4 or not os.path.exists(yuv):
            raise DamagedFile("damaged video layer (dec265 failed)")
        width, height = int(fields["pic_width_in_luma_samples"]), int(fields["pic_height_in_luma_samples"])
        depth, chroma = int(fields["bit_depth_luma"]), int(fields["chroma_format_idc"])
        if chroma != 0 or not 8 <= depth <= 12 or width < sx or height < sy:
            raise DamagedFile("damaged video layer (not monochrome pictures of the slices)")
        with open(yuv, "rb") as f:
            data = f.read()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    size = 1 if depth == 8 else 2
    if len(data) % sz:
        raise DamagedFile("damaged video layer (%d pictures for %d slices?)" % (len(data), sz))
    frame = len(data) // sz  # dec265 may add neutral chroma planes after each monochrome picture
    if frame < width * height * size:
        raise DamagedFile("damaged video layer (pictures do not hold the slices)")
    samples = []
    for z in range(sz):
        for y in range(sy):
            row = z * frame + y * width * size
            if size == 1:
                samples.extend(data[row:row + sx])
            else:
                samples.extend(struct.unpack("<%dH" % sx, data[row:row + 2 * sx]))
    return samples


def decode_av1_layer(h):
    """Section "Video layer" with form bit 4: the samples r in grid order (x fastest), decoded by dav1d (the
    dav1d package) from the AV1 stream (low-overhead OBUs): picture z's top-left size x by size y samples
    are slice z."""
    import os
    import re
    import shutil
    import subprocess
    import tempfile
    if shutil.which("dav1d") is None:
        raise DamagedFile("dav1d (the dav1d package) is needed to decode an AV1 video layer")
    sx, sy, sz = h["size"]
    work = tempfile.mkdtemp(prefix="dcv-av1-")
    try:
        stream, y4m = os.path.join(work, "layer.obu"), os.path.join(work, "layer.y4m")
        with open(stream, "wb") as out:
            out.write(h["residual_layer"])
        run = subprocess.run(["dav1d", "-q", "--demuxer", "section5", "--threads", "1", "--filmgrain", "0",
                              "-i", stream, "-o", y4m], capture_output=True)
        if run.returncode != 0 or not os.path.exists(y4m):
            raise DamagedFile("damaged video layer (dav1d failed)")
        with open(y4m, "rb") as f:
            data = f.read()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    end = data.find(b"\n")
    header = data[:end].decode("ascii", "replace")
    m = re.match(r"YUV4MPEG2 W(\d+) H(\d+) .*\bC(mono(?:10|12)?)\b", header)
    if not m:
        raise DamagedFile("damaged video layer (not monochrome pictures)")
    width, height = int(m.group(1)), int(m.group(2))
    size = 1 if m.group(3) == "mono" else 2
    if width < sx or height < sy:
        raise DamagedFile("damaged video layer (pictures smaller than the slices)")
    frame = len(b"FRAME\n") + width * height * size
    body = data[end + 1:]
    if len(body) != frame * sz:
        raise DamagedFile("damaged video layer (%d bytes of pictures for %d slices)" % (len(body), sz))
    samples = []
    for z in range(sz):
        if body[z * frame:z * frame + 6] != b"FRAME\n":
            raise DamagedFile("damaged video layer (a picture without its FRAME line)")
        for y in range(sy):
            row = z * frame + 6 + y * width * size
            if size == 1:
                samples.extend(body[row:row + sx])
            else:
                samples.extend(struct.unpack("<%dH" % sx, body[row:row + 2 * sx]))
    return samples


def decode_residual_layer(h):
    """Section "Residual layer": the samples r in grid order (x fastest), decoded by OpenJPEG's
    opj_decompress (libopenjp2-tools) from the codestream, then taken out of the slice mosaic."""
    import os
    import shutil
    import subprocess
    import tempfile
    if h["form"] & FORM_BOUNDED:
        return decode_bounded_layer(h)
    if h["form"] & FORM_AV1:
        return decode_av1_layer(h)
    if h["form"] & FORM_VIDEO:
        return decode_video_layer(h)
    if shutil.which("opj_decompress") is None:
        raise DamagedFile("opj_decompress (libopenjp2-tools) is needed to decode the residual layer")
    sx, sy, sz = h["size"]
    work = tempfile.mkdtemp(prefix="dcv-residual-")
    try:
        j2k, pgx = os.path.join(work, "layer.j2k"), os.path.join(work, "layer.pgx")
        with open(j2k, "wb") as out:
            out.write(h["residual_layer"])
        run = subprocess.run(["opj_decompress", "-i", j2k, "-o", pgx], capture_output=True)
        # One component: layer.pgx (or layer_0.pgx); several: layer_0.pgx, layer_1.pgx, ...
        produced = sorted((n for n in os.listdir(work) if n.endswith(".pgx")),
                          key=lambda n: int(n[6:-4]) if n[5:6] == "_" else 0)
        if run.returncode != 0 or not produced:
            raise DamagedFile("damaged residual layer (opj_decompress failed)")
        planes = []
        for name in produced:
            with open(os.path.join(work, name), "rb") as f:
                planes.append(read_pgx(f.read()))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    samples = []
    if len(planes) > 1:  # one component per slice
        if len(planes) != sz or any(w != sx or hh != sy for w, hh, _ in planes):
            raise DamagedFile("damaged residual layer (neither a mosaic nor one component per slice)")
        for _, _, plane in planes:
            samples.extend(plane)
        return inverse_inter_slice(samples, h["size"], h["residual_levels"]) if h["residual_levels"] else samples
    width, height, mosaic = planes[0]
    if width % sx or height % sy or height // sy != -(-sz // (width // sx)):
        raise DamagedFile("damaged residual layer (not a mosaic of %d slices of %dx%d samples)" % (sz, sx, sy))
    columns = width // sx
    for z in range(sz):
        x0, y0 = (z % columns) * sx, (z // columns) * sy
        for y in range(sy):
            row = (y0 + y) * width + x0
            samples.extend(mosaic[row:row + sx])
    return inverse_inter_slice(samples, h["size"], h["residual_levels"]) if h["residual_levels"] else samples


def print_header(h):
    print("version", h["version"])
    print("pixel_type", h["pixel_type"], PIXEL_TYPES[h["pixel_type"]])
    print("flags", h["flags"])
    print("mode", h["mode"], MODES.get(h["mode"], "unknown"))
    print("size", *h["size"])
    print("spacing", *map(repr, h["spacing"]))
    print("origin", *map(repr, h["origin"]))
    print("direction", *map(repr, h["direction"]))
    print("scale", *h["scale"])
    print("quantization_origin", repr(h["q0"]))
    print("quantization_step", repr(h["q"]))
    print("points", h["n"])
    print("payload_bytes", len(h["payload"]))
    if h["flags"] & FLAG_RESIDUAL:
        print("form", h["form"])
        print("residual_step", repr(h["residual_step"]))
        print("residual_levels", h["residual_levels"])
        print("residual_bytes", len(h["residual_layer"]))
        if h["form"] & FORM_BOUNDED:  # the bound the layer states (checked when the layer was decoded)
            print("maximum_error", repr(read_bounded_layer(h["residual_layer"], h["size"])[0]))
    for key, value in h["metadata"]:
        if key == DICOM_HEADER_KEY:
            mode, common, files = value
            value = "%s, %d files, %d bytes common, %d per file in all" % (
                ("full", "essential")[mode], len(files), len(common), sum(len(f) for f in files))
        print("metadata", json.dumps(key, ensure_ascii=False), json.dumps(value, ensure_ascii=False))


def main():
    parser = argparse.ArgumentParser(description="Reference decoder of .dcv files (docs/format.md).")
    parser.add_argument("file", metavar="FILE.dcv")
    parser.add_argument("--neighbours", metavar="FILE",
                        help="neighbour lists (one line per vertex, in position order): decode the values too")
    args = parser.parse_args()
    try:
        with open(args.file, "rb") as f:
            data = f.read()
    except OSError as e:
        print("%s: cannot be read (%s)" % (args.file, e.strerror), file=sys.stderr)
        return 2
    try:
        h = parse_container(data)
        if h["form"] & FORM_CONSTANT:  # the 8 corners, all at q0 (in position order: z, then y, then x)
            sx, sy, sz = h["size"]
            points = [(x, y, z) for z in (0, sz - 1) for y in (0, sy - 1) for x in (0, sx - 1)]
        else:
            d = ArithmeticDecoder(h["payload"])
            points = decode_positions(d, h["size"], h["n"])
            check_positions(d, h["size"], points)
        values = None
        if args.neighbours:
            try:
                neighbours = read_neighbours(args.neighbours, h["n"])
            except (OSError, ValueError) as e:
                print("%s: %s" % (args.neighbours, e.strerror if isinstance(e, OSError) else e), file=sys.stderr)
                return 2
            values = [h["q0"]] * 8 if h["form"] & FORM_CONSTANT else decode_values(d, neighbours, h["q0"], h["q"])
        residual = decode_residual_layer(h) if h["flags"] & FLAG_RESIDUAL else None
    except DamagedFile as e:
        print("%s: %s" % (args.file, e), file=sys.stderr)
        return 1
    print_header(h)
    if residual is not None:
        # CRC-32 of the samples as 32-bit little-endian integers: one line for the whole layer.
        print("residual_crc", zlib.crc32(struct.pack("<%di" % len(residual), *residual)) & 0xFFFFFFFF)
    if values is None:
        sys.stdout.writelines("%d %d %d\n" % p for p in points)
    else:
        sys.stdout.writelines("%d %d %d %r\n" % (p[0], p[1], p[2], v) for p, v in zip(points, values))
    return 0


if __name__ == "__main__":
    sys.exit(main())
