#!/usr/bin/python3
"""Rate-distortion comparison of dcv against public codecs on the same volume and byte budget.

For every volume and every budget bpv, the budget in bytes is B = floor(bpv * voxels / 8) and each codec
is tuned to the best PSNR (MSE over all voxels, against the original values) among the settings whose WHOLE
output file has at most B bytes:

  dcv         build/tools/dcv/dcv compress --bpv R (R = bpv; lowered only if the file exceeds B), decompress, PSNR
  j2k-comp    OpenJPEG, the z slices as the components of one 2D image (raw input, -mct 0); -r searched
  j2k-mosaic  OpenJPEG, the z slices tiled into one near-square 2D PGM mosaic; -r searched
  x265        HEVC, the z slices as frames of a 4:0:0 video (--preset slower --tune psnr); --crf searched
  av1         aomenc --monochrome --end-usage=q --cpu-used=4; --cq-level searched (and 2-pass VBR)

PSNR peak: 255 for uint8 volumes, max - min of the original for other types (the project README's
convention). The peers code unsigned integers: uint8 volumes as they are; other integer volumes (e.g. the
int16 headsq-ct.nrrd) minus their minimum (added back after decoding), at the bit depth their range needs:
OpenJPEG up to 16 bits (raw -F X,Y,Z,bits,u / 16-bit PGM), x265 and aomenc at 8, 10 or 12 bits (a range
needing more than 12 bits is right-shifted, noted). Float volumes get dcv only.

Default volumes: every *.nrrd and every dicom-* series directory in ../shared/data (a series is compressed
by dcv as a directory, DICOM attributes included, and given to the peers as `dcv convert` writes it, in
Hounsfield units), norm-256.nrrd (256^3) included; it is the slow one (on 2 busy
cores: x265 searched 0.03125 bpv on it in ~2 minutes, the four peers at the four rates took ~28 minutes).

Results: a Markdown table on stdout and in build/rd/rd.md, a CSV in build/rd/rd.csv and one PNG plot per
volume (PSNR vs bpv) in build/rd/. --merge adds the rows of earlier runs' rd.csv files (this run's rows win
for the same volume, bpv and codec), e.g. run the peers once and re-run dcv alone later.

Examples:
  scripts/rd_benchmark.py --volumes head-mr.nrrd flair-mr.nrrd --bpv 0.03125
  scripts/rd_benchmark.py --codecs j2k-comp j2k-mosaic x265 av1 --out build/rd-peers
  scripts/rd_benchmark.py --codecs dcv --merge build/rd-peers/rd.csv
"""

import argparse
import csv
import gzip
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

try:
    import numpy as np
except ImportError:
    sys.exit("rd_benchmark: python3-numpy is missing (apt-get install python3-numpy); run with /usr/bin/python3")

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_DATA = os.path.normpath(os.path.join(REPO, "..", "shared", "data"))
DEFAULT_BPVS = [0.03125, 0.0625, 0.125, 0.25]
CODECS = ["dcv", "j2k-comp", "j2k-mosaic", "x265", "av1"]
TOOLS = {
    "j2k-comp": ["opj_compress", "opj_decompress"],
    "j2k-mosaic": ["opj_compress", "opj_decompress"],
    "x265": ["x265"],
    "av1": ["aomenc", "aomdec"],
}
APT = {"opj_compress": "libopenjp2-tools", "opj_decompress": "libopenjp2-tools", "x265": "x265",
       "aomenc": "aom-tools", "aomdec": "aom-tools", "ffmpeg": "ffmpeg"}
TIMEOUT = 1800
AV1_FPS = 1000  # y4m frame rate for aomenc (no timing info is coded in the OBU stream by default)

# ----------------------------------------------------------------------------------------------------- NRRD

NRRD_TYPES = {
    "uchar": "u1", "unsigned char": "u1", "uint8": "u1", "uint8_t": "u1",
    "signed char": "i1", "int8": "i1", "int8_t": "i1", "char": "i1",
    "short": "i2", "short int": "i2", "signed short": "i2", "signed short int": "i2", "int16": "i2",
    "int16_t": "i2",
    "ushort": "u2", "unsigned short": "u2", "unsigned short int": "u2", "uint16": "u2", "uint16_t": "u2",
    "int": "i4", "signed int": "i4", "int32": "i4", "int32_t": "i4",
    "uint": "u4", "unsigned int": "u4", "uint32": "u4", "uint32_t": "u4",
    "float": "f4", "double": "f8",
}


def read_nrrd(path):
    """Return a (z, y, x) numpy array (x fastest in the file). Supports attached raw and gzip data."""
    with open(path, "rb") as f:
        data = f.read()
    if not data.startswith(b"NRRD"):
        raise ValueError(f"{path}: not a NRRD file")
    fields = {}
    pos = data.index(b"\n") + 1
    while True:
        end = data.index(b"\n", pos)
        line = data[pos:end].decode("latin-1").rstrip("\r")
        pos = end + 1
        if line == "":
            break
        if line.startswith("#") or ":=" in line:
            continue
        key, _, value = line.partition(":")
        fields[key.strip().lower()] = value.strip()
    if "data file" in fields or "datafile" in fields:
        raise ValueError(f"{path}: detached data is not supported")
    sizes = [int(s) for s in fields["sizes"].split()]
    dt = NRRD_TYPES[fields["type"].lower()]
    if dt[1] != "1":
        dt = (">" if fields.get("endian", "little").lower() == "big" else "<") + dt
    enc = fields.get("encoding", "raw").lower()
    payload = data[pos:]
    if enc in ("gzip", "gz"):
        payload = gzip.decompress(payload)
    elif enc != "raw":
        raise ValueError(f"{path}: encoding {enc} is not supported")
    count = int(np.prod(sizes))
    arr = np.frombuffer(payload, dtype=np.dtype(dt), count=count)
    return arr.reshape(sizes[::-1]).copy()  # (z, y, x)


def psnr(ref, test, peak):
    mse = np.mean((ref.astype(np.float64) - test.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10.0 * math.log10(peak * peak / mse)


# ------------------------------------------------------------------------- the peers' unsigned integer samples

OPJ_DEPTHS = list(range(8, 17))  # opj_compress raw / PGM input holds at most 16 bits a sample
VIDEO_DEPTHS = [8, 10, 12]  # x265 (Debian's is built 8bit+10bit+12bit) and aomenc (high bit depth build)


def peer_samples(vol):
    """The unsigned samples the peers code: uint8 volumes as they are; other integer volumes minus their
    minimum (the peers take unsigned input; added back by restore()), with the bit depth the range max - min
    needs (at least 8). None for float volumes (the peers are skipped)."""
    if vol.dtype == np.uint8:
        return dict(codes=vol, offset=0, bits=8)
    if not np.issubdtype(vol.dtype, np.integer):
        return None
    lo = int(vol.min())
    bits = max(8, (int(vol.max()) - lo).bit_length())
    return dict(codes=vol.astype(np.int64) - lo, offset=lo, bits=bits)


def codec_depth(bits, depths):
    """(coded bit depth, right shift): the smallest depth in `depths` that holds `bits`, else the largest
    one with the samples right-shifted by the excess."""
    for d in sorted(depths):
        if d >= bits:
            return d, 0
    return max(depths), bits - max(depths)


def coded(s, depth, shift):
    """The samples as the codec gets them: uint8 at 8 bits, else uint16 (little-endian in files)."""
    return (s["codes"] >> shift).astype(np.uint8 if depth == 8 else "<u2")


def restore(s, rec, shift):
    """Decoded samples -> values in the original range: undo the right shift (to the middle of the dropped
    interval, clipped to the range's bit depth) and add the minimum back."""
    r = rec.astype(np.int64)
    if shift:
        r = np.minimum((r << shift) + (1 << (shift - 1)), (1 << s["bits"]) - 1)
    return r + s["offset"]


def depth_note(depth, shift):
    return "" if depth == 8 and not shift else f"; {depth}-bit" + (f", samples >> {shift}" if shift else "")


class ToolError(RuntimeError):
    def __init__(self, msg, returncode):
        super().__init__(msg)
        self.returncode = returncode


def run(cmd, cwd=None):
    """Run cmd; return wall seconds. Raise ToolError with stderr on failure."""
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       timeout=TIMEOUT)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        raise ToolError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.decode(errors='replace')[-600:]}",
                        p.returncode)
    return dt


# --------------------------------------------------------------------------------------------- search helpers

class Trials:
    """Keeps every trial; best() is the highest PSNR among those whose file fits the budget."""

    def __init__(self, budget):
        self.budget = budget
        self.all = {}

    def add(self, key, res):
        self.all[key] = res
        return res

    def best(self):
        fit = [r for r in self.all.values() if r is not None and r["bytes"] <= self.budget]
        return max(fit, key=lambda r: (r["psnr"], r["bytes"])) if fit else None

    def smallest(self):
        ok = [r for r in self.all.values() if r is not None]
        return min(ok, key=lambda r: r["bytes"]) if ok else None


def search_continuous(trial, budget, x0, lo_lim, hi_lim, iters):
    """trial(x) -> result with 'bytes'; the file shrinks as x grows (roughly). Find the smallest x that fits
    by geometric bracketing from x0 then bisection in log space. Returns nothing; trial() records."""
    x = min(max(x0, lo_lim), hi_lim)
    r = trial(x)
    if r["bytes"] <= budget:
        hi = x
        lo = None
        while lo is None:
            y = max(hi / 1.6, lo_lim)
            if y >= hi:  # at the best-quality end and it fits
                return
            if trial(y)["bytes"] <= budget:
                hi = y
            else:
                lo = y
    else:
        lo = x
        hi = None
        while hi is None:
            y = min(lo * 1.6, hi_lim)
            if y <= lo:
                return  # nothing fits
            if trial(y)["bytes"] <= budget:
                hi = y
            else:
                lo = y
    for _ in range(iters):
        mid = math.sqrt(lo * hi) if lo > 0 else (lo + hi) / 2
        if trial(mid)["bytes"] <= budget:
            hi = mid
        else:
            lo = mid


def search_linear(trial, budget, x0, lo_lim, hi_lim, iters):
    """Same as search_continuous for a parameter on a linear scale (x265 crf)."""
    lo, hi = lo_lim, hi_lim
    if trial(hi)["bytes"] > budget:
        return
    if trial(lo)["bytes"] <= budget:
        return
    for _ in range(iters):
        mid = (lo + hi) / 2
        if trial(mid)["bytes"] <= budget:
            hi = mid
        else:
            lo = mid


def search_int(trial, budget, lo_lim, hi_lim, extra=2):
    """Integer parameter, the file shrinks as it grows: bisection for the smallest fitting value, then also
    the next `extra` values (rate is not strictly monotonic)."""
    if trial(hi_lim)["bytes"] > budget:
        return
    lo, hi = lo_lim, hi_lim
    if trial(lo)["bytes"] <= budget:
        hi = lo
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if trial(mid)["bytes"] <= budget:
            hi = mid
        else:
            lo = mid
    for v in range(hi + 1, min(hi + extra, hi_lim) + 1):
        trial(v)


# ------------------------------------------------------------------------------------------------------ codecs

def codec_dcv(vol, path, budget, bpv, work, ctx):
    dcv = ctx["dcv"]
    nvox = vol.size
    peak = ctx["peak"]
    out = os.path.join(work, "out.dcv")
    dec = os.path.join(work, "dec.nrrd")
    rate = bpv
    result = None
    notes = []
    for attempt in range(4):
        t_enc = run([dcv, "compress", path, out, "--bpv", repr(rate), "-f", "-q"])
        size = os.path.getsize(out)
        t_dec = run([dcv, "decompress", out, dec, "-f", "-q"])
        rec = read_nrrd(dec)
        result = dict(bytes=size, psnr=psnr(vol, rec, peak), enc=t_enc, dec=t_dec, setting=f"--bpv {rate:.6g}")
        if size <= budget:
            break
        notes.append(f"--bpv {rate:.6g} gave {size} B > {budget} B")
        rate = rate * budget / size * 0.99
    if result["bytes"] > budget:
        result["setting"] += " (OVER BUDGET)"
    if notes:
        result["setting"] += "; " + "; ".join(notes)
    return result


def opj_common(lossy97, nres):
    args = ["-n", str(nres)]
    if lossy97:
        args.append("-I")
    return args


def opj_nres(w, h):
    # OpenJPEG needs every resolution level to have at least one sample; default is 6
    return max(1, min(6, int(math.floor(math.log2(max(1, min(w, h))))) + 1))


def codec_j2k_comp(vol, path, budget, bpv, work, ctx):
    s = ctx["samples"]
    depth, shift = codec_depth(s["bits"], OPJ_DEPTHS)
    z0, y0, x0 = vol.shape
    pv, pad_note = opj_raw_pad(coded(s, depth, shift), depth)
    pad_note = depth_note(depth, shift) + pad_note
    z, y, x = pv.shape
    # deeper than 8 bits: 2 bytes a sample, little-endian (.rawl; opj_decompress writes .rawl the same way,
    # while its .raw output is not the big-endian that opj_compress reads from .raw)
    ext = "raw" if depth == 8 else "rawl"
    raw = os.path.join(work, f"vol.{ext}")
    pv.tofile(raw)
    rawbytes = pv.size * depth / 8  # what the -r ratios refer to
    nres = opj_nres(x, y)
    best_all = []
    for lossy97 in (True, False):
        tr = Trials(budget)

        def trial(r, lossy97=lossy97, tr=tr):
            key = round(r, 6)
            if key in tr.all:
                return tr.all[key]
            out = os.path.join(work, f"o_{lossy97:d}_{key}.j2k")
            t_enc = run(["opj_compress", "-i", raw, "-o", out, "-F", f"{x},{y},{z},{depth},u", "-r", f"{r:.6f}",
                         "-mct", "0"] + opj_common(lossy97, nres))
            size = os.path.getsize(out)
            res = dict(bytes=size, enc=t_enc, psnr=float("-inf"), dec=None,
                       setting=f"-r {r:.4f} {'-I (9/7)' if lossy97 else '5/3'} -n {nres}{pad_note}")
            if size <= budget:
                dec = os.path.join(work, f"dec.{ext}")
                res["dec"] = run(["opj_decompress", "-i", out, "-o", dec])
                rec = np.fromfile(dec, dtype=pv.dtype)
                if rec.size != pv.size:
                    raise RuntimeError(f"opj_decompress wrote {rec.size} samples, expected {pv.size}")
                rec = rec.reshape(pv.shape)[:z0, :y0, :x0]
                res["psnr"] = psnr(vol, restore(s, rec, shift), ctx["peak"])
                os.remove(dec)
            os.remove(out)
            return tr.add(key, res)

        search_continuous(trial, budget, rawbytes / budget, 1.0, rawbytes * 4.0, 9)
        best_all.append((tr.best(), tr.smallest()))
    return pick(best_all, budget)


def opj_raw_pad(vol, bits):
    """opj_compress (OpenJPEG 2.5 convert.c rawtoimage_common) rejects raw input when width & height & ncomp &
    bitdepth != 0 (a bitwise-AND bug: with 8-bit data it fails whenever width, height and ncomp all have bit 3
    set; checked to hold for 12-bit data too). Work around it with the cheapest edge-replicated padding of x,
    y or z that makes the AND 0; the padding is cropped before PSNR and its bits count against the budget."""
    z, y, x = vol.shape
    if (x & y & z & bits) == 0:
        return vol, ""
    dims = dict(x=x, y=y, z=z)

    def nxt(axis):
        others = bits
        for a, n in dims.items():
            if a != axis:
                others &= n
        m = dims[axis]
        while m & others:
            m += 1
        return m
    cands = [((nxt(a) - dims[a]) * (x * y * z // dims[a]), a, nxt(a)) for a in "xyz"]
    _, axis, n = min(cands)
    pads = {"z": ((0, n - z), (0, 0), (0, 0)), "y": ((0, 0), (0, n - y), (0, 0)), "x": ((0, 0), (0, 0), (0, n - x))}
    return (np.pad(vol, pads[axis], mode="edge"),
            f"; {axis} padded {dims[axis]}->{n} (opj_compress -F bitwise-AND bug workaround)")


def mosaic_layout(z, y, x):
    best = None
    for cols in range(1, z + 1):
        rows = -(-z // cols)
        w, h = cols * x, rows * y
        score = (max(w, h) / min(w, h), rows * cols - z)
        if best is None or score < best[0]:
            best = (score, cols, rows)
    return best[1], best[2]


def codec_j2k_mosaic(vol, path, budget, bpv, work, ctx):
    s = ctx["samples"]
    depth, shift = codec_depth(s["bits"], OPJ_DEPTHS)
    cv = coded(s, depth, shift)
    z, y, x = vol.shape
    cols, rows = mosaic_layout(z, y, x)
    img = np.zeros((rows * y, cols * x), dtype=cv.dtype)
    for k in range(z):
        r, c = divmod(k, cols)
        img[r * y:(r + 1) * y, c * x:(c + 1) * x] = cv[k]
    H, W = img.shape
    pgm = os.path.join(work, "mosaic.pgm")
    with open(pgm, "wb") as f:
        # opj_compress takes the precision from maxval; PGM samples deeper than 8 bits are 2 bytes big-endian
        f.write(f"P5\n{W} {H}\n{(1 << depth) - 1}\n".encode())
        f.write(img.astype(">u2" if depth > 8 else np.uint8).tobytes())
    nres = opj_nres(W, H)
    best_all = []
    for lossy97 in (True, False):
        tr = Trials(budget)

        def trial(r, lossy97=lossy97, tr=tr):
            key = round(r, 6)
            if key in tr.all:
                return tr.all[key]
            out = os.path.join(work, f"o_{lossy97:d}_{key}.j2k")
            command = ["opj_compress", "-i", pgm, "-o", out, "-r", f"{r:.6f}"] + opj_common(lossy97, nres)
            t_enc = run(command)
            size = os.path.getsize(out)
            res = dict(bytes=size, enc=t_enc, psnr=float("-inf"), dec=None, command=command,
                       setting=f"-r {r:.4f} {'-I (9/7)' if lossy97 else '5/3'} -n {nres}; mosaic {cols}x{rows} "
                               f"tiles = {W}x{H} px, empty tiles 0{depth_note(depth, shift)}")
            if size <= budget:
                dec = os.path.join(work, "dec.pgm")
                res["dec"] = run(["opj_decompress", "-i", out, "-o", dec])
                rimg = read_pgm(dec)
                rec = np.empty_like(cv)
                for k in range(z):
                    rr, c = divmod(k, cols)
                    rec[k] = rimg[rr * y:(rr + 1) * y, c * x:(c + 1) * x]
                res["psnr"] = psnr(vol, restore(s, rec, shift), ctx["peak"])
                os.remove(dec)
            os.remove(out)
            return tr.add(key, res)

        search_continuous(trial, budget, img.size * depth / 8 / budget, 1.0, img.size * depth / 2, 9)
        best_all.append((tr.best(), tr.smallest()))
    return pick(best_all, budget)


def read_pgm(path):
    with open(path, "rb") as f:
        data = f.read()
    tokens = []
    pos = 0
    while len(tokens) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        tokens.append(data[start:pos].decode())
    pos += 1
    if tokens[0] != "P5" or int(tokens[3]) > 65535:
        raise ValueError(f"{path}: only P5 PGM is supported")
    w, h = int(tokens[1]), int(tokens[2])
    dt = np.dtype(np.uint8) if int(tokens[3]) < 256 else np.dtype(">u2")  # maxval > 255: 2 bytes big-endian
    return np.frombuffer(data[pos:pos + w * h * dt.itemsize], dtype=dt).reshape(h, w)


def pad_xy(vol, mult):
    z, y, x = vol.shape
    py, px = (-y) % mult, (-x) % mult
    if py or px:
        vol = np.pad(vol, ((0, 0), (0, py), (0, px)), mode="edge")
    return vol


def codec_x265(vol, path, budget, bpv, work, ctx):
    s = ctx["samples"]
    depth, shift = codec_depth(s["bits"], VIDEO_DEPTHS)
    z, y, x = vol.shape
    pv = pad_xy(coded(s, depth, shift), 8)
    _, Y, X = pv.shape
    yuv = os.path.join(work, "vol.yuv")
    pv.tofile(yuv)
    # Above 8 bits: no --profile (x265 refuses main10/main12 with i400 input; it codes a RExt monochrome
    # stream), and PSNR from an ffmpeg decode of every fitting trial because Debian's multilib x265 3.5 writes
    # its --recon file with 8-bit samples for a 10/12-bit encode.
    if depth > 8 and shutil.which("ffmpeg") is None:
        raise RuntimeError(f"ffmpeg is needed to decode {depth}-bit x265 streams (apt-get install ffmpeg)")
    pix_fmt = "gray" if depth == 8 else f"gray{depth}le"
    base = ["x265", "--input", yuv, "--input-res", f"{X}x{Y}", "--input-csp", "i400", "--input-depth", str(depth),
            "--output-depth", str(depth), "--fps", "25", "--preset", "slower", "--tune", "psnr", "--no-info"]

    def ffmpeg_decode(stream):
        """(seconds, decoded samples cropped to the volume, or None if ffmpeg returned the wrong count)"""
        dec = os.path.join(work, "dec.yuv")
        secs = run(["ffmpeg", "-v", "error", "-y", "-threads", "1", "-i", stream, "-f", "rawvideo",
                    "-pix_fmt", pix_fmt, dec])
        d = np.fromfile(dec, dtype=pv.dtype)
        os.remove(dec)
        return secs, (d.reshape(z, Y, X)[:, :y, :x] if d.size == z * Y * X else None), d.size

    def search(ctu):
        tr = Trials(budget)

        def trial(crf):
            key = round(crf, 4)
            if key in tr.all:
                return tr.all[key]
            out = os.path.join(work, "out.hevc")
            recon = os.path.join(work, "recon.yuv")
            command = base + ["--ctu", str(ctu), "--crf", f"{crf:.4f}", "-o", out]
            t_enc = run(command + (["--recon", recon] if depth == 8 else []))
            size = os.path.getsize(out)
            setting = f"--crf {crf:.3f} --ctu {ctu}"
            if (X, Y) != (x, y):
                setting += f"; {X}x{Y} (padded from {x}x{y})"
            setting += depth_note(depth, shift)
            res = dict(bytes=size, enc=t_enc, psnr=float("-inf"), dec=None, setting=setting, command=command)
            if size <= budget:
                if depth == 8:
                    rec = np.fromfile(recon, dtype=np.uint8).reshape(z, Y, X)[:, :y, :x]
                else:
                    res["dec"], rec, n = ffmpeg_decode(out)
                    if rec is None:
                        raise RuntimeError(f"ffmpeg decoded {n} samples, expected {z * Y * X}")
                res["psnr"] = psnr(vol, restore(s, rec, shift), ctx["peak"])
                keep = os.path.join(work, f"out_{key}.hevc")
                shutil.copyfile(out, keep)
                res["file"] = keep
                res["recon"] = rec
            return tr.add(key, res)

        search_linear(trial, budget, 28.0, 0.0, 51.0, 9)
        return tr

    # the largest CTU the picture holds (x265 refuses pictures smaller than one CTU). Debian's x265 3.5 aborts
    # (heap corruption) on some 10/12-bit encodes, e.g. 48x64 at --ctu 32 (64x64 at 64 or 32 is fine): then
    # the search is redone with the next smaller CTU
    ctus = [c for c in (64, 32, 16) if c <= min(X, Y)] or [16]
    aborted = []
    for ctu in ctus:
        try:
            tr = search(ctu)
            break
        except ToolError as e:
            if depth == 8 or e.returncode >= 0 or ctu == ctus[-1]:
                raise
            aborted.append(f"x265 aborted ({e.returncode}) at --ctu {ctu}")
    best = tr.best()
    if best is None:
        return nofit(tr.smallest(), budget, "x265 at --crf 51" + "".join(f"; {a}" for a in aborted))
    best["setting"] += "".join(f"; {a}" for a in aborted)
    if depth > 8:
        best["setting"] += "; PSNR from the ffmpeg decode"
    # 8 bits: real decode of the chosen stream with ffmpeg (x265 has no decoder), check it equals the recon
    elif shutil.which("ffmpeg"):
        best["dec"], d, n = ffmpeg_decode(best["file"])
        if d is None:
            best["setting"] += f"; ffmpeg decode has {n} samples (expected {z * Y * X}): PSNR from recon"
        elif np.array_equal(d, best["recon"]):
            best["setting"] += "; ffmpeg decode == recon"
        else:
            best["psnr"] = psnr(vol, restore(s, d, shift), ctx["peak"])
            best["setting"] += f"; ffmpeg decode != recon (decode PSNR {best['psnr']:.3f})"
    else:
        best["setting"] += "; PSNR from x265 --recon (ffmpeg missing: no decode time)"
    return best


def codec_av1(vol, path, budget, bpv, work, ctx):
    s = ctx["samples"]
    depth, shift = codec_depth(s["bits"], VIDEO_DEPTHS)
    cv = coded(s, depth, shift)
    z, y, x = vol.shape
    container = ctx["av1_container"]
    y4m = os.path.join(work, "vol.y4m")
    # aomenc's y4m reader has no 10/12-bit mono: above 8 bits the input is 4:2:0 with flat dummy chroma, which
    # --monochrome drops (the stream and aomdec's output are luma only)
    cw, ch = (x + 1) // 2, (y + 1) // 2
    chroma = b"" if depth == 8 else np.full(2 * cw * ch, 1 << (depth - 1), dtype="<u2").tobytes()
    cspace = "Cmono" if depth == 8 else f"C420p{depth} XYSCSS=420P{depth}"
    with open(y4m, "wb") as f:
        # frame rate only scales the VBR target (kbit/s, an integer): 1000 fps gives ~1000/8/1000*frames B steps
        f.write(f"YUV4MPEG2 W{x} H{y} F{AV1_FPS}:1 Ip A1:1 {cspace}\n".encode())
        for k in range(z):
            f.write(b"FRAME\n")
            f.write(cv[k].tobytes())
            f.write(chroma)
    # 12 bits needs AV1's professional profile (2); 8 and 10 bits fit the main profile (0)
    depth_args = [f"--input-bit-depth={depth}", f"--bit-depth={depth}"] + (["--profile=2"] if depth == 12 else [])
    tr = Trials(budget)

    def trial(cq):
        if cq in tr.all:
            return tr.all[cq]
        if isinstance(cq, tuple):  # ("vbr", inverse kbps): 2-pass VBR with a target bitrate
            kbps = max(1, int(round(1.0 / cq[1])))
            key = ("vbr", kbps)
            if key in tr.all:
                return tr.all[key]
            rc = ["--end-usage=vbr", f"--target-bitrate={kbps}"]
            label = f"--end-usage=vbr --target-bitrate={kbps} (kbit/s at {AV1_FPS} fps)"
        else:
            key = cq
            rc = ["--end-usage=q", f"--cq-level={cq}"]
            label = f"--end-usage=q --cq-level={cq}"
        out = os.path.join(work, f"out.{container}")
        t_enc = run(["aomenc"] + depth_args + ["--monochrome"] + rc +
                    ["--cpu-used=4", f"--{container}", "-q", "-o", out, y4m])
        size = os.path.getsize(out)
        res = dict(bytes=size, enc=t_enc, psnr=float("-inf"), dec=None,
                   setting=f"{label} --cpu-used=4 --{container} (y4m {cspace.split()[0]} input)"
                           + depth_note(depth, shift))
        if size <= budget:
            dec = os.path.join(work, "dec.yuv")
            res["dec"] = run(["aomdec", "--rawvideo", "-o", dec, out])
            d = np.fromfile(dec, dtype=cv.dtype)  # aomdec writes 2 bytes a sample above 8 bits
            if d.size == z * y * x:
                rec = d.reshape(z, y, x)
            else:  # 4:2:0 output with dummy chroma: take the luma planes
                fs = y * x + 2 * cw * ch
                if d.size != z * fs:
                    raise RuntimeError(f"aomdec wrote {d.size} samples, expected {z * y * x} or {z * fs}")
                rec = d.reshape(z, fs)[:, :y * x].reshape(z, y, x)
            res["psnr"] = psnr(vol, restore(s, rec, shift), ctx["peak"])
            os.remove(dec)
        os.remove(out)
        return tr.add(key, res)

    search_int(trial, budget, 0, 63)
    # cq-level is coarse at low rates (one step can be >10% of the budget): also search the target bitrate of
    # 2-pass VBR (parameter: 1/kbps, the file shrinks as it grows) and keep the better of the two
    kbps0 = budget * 8.0 * AV1_FPS / z / 1000.0
    search_continuous(lambda inv: trial(("vbr", inv)), budget, 1.0 / kbps0, 1e-4, 1.0, 7)
    best = tr.best()
    return best if best else nofit(tr.smallest(), budget, "aomenc (--cq-level up to 63 and VBR down to 1 kbit/s)")


def pick(best_all, budget):
    fits = [b for b, _ in best_all if b is not None]
    if fits:
        return max(fits, key=lambda r: r["psnr"])
    smallest = min((s for _, s in best_all if s is not None), key=lambda r: r["bytes"], default=None)
    return nofit(smallest, budget, "opj_compress at the largest ratio tried")


def nofit(smallest, budget, what):
    msg = f"NO FIT: {what}"
    if smallest is not None:
        msg += f": smallest file {smallest['bytes']} B > {budget} B ({smallest['setting']})"
    return dict(bytes=None, psnr=None, enc=None, dec=None, setting=msg)


CODEC_FUNCS = {"dcv": codec_dcv, "j2k-comp": codec_j2k_comp, "j2k-mosaic": codec_j2k_mosaic, "x265": codec_x265,
               "av1": codec_av1}

# ------------------------------------------------------------------------------------------------------ output


ROW_KEYS = ["volume", "bpv", "budget", "codec", "bytes", "abpv", "psnr", "enc", "dec", "setting"]


def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def markdown(rows, notes):
    lines = ["| volume | bpv | budget B | codec | bytes | actual bpv | PSNR dB | encode s | decode s | setting |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['volume']} | {r['bpv']:g} | {r['budget']} | {r['codec']} | {fmt(r['bytes'], 'd')} | "
                     f"{fmt(r['abpv'], '.5f')} | {fmt(r['psnr'], '.3f')} | {fmt(r['enc'], '.2f')} | "
                     f"{fmt(r['dec'], '.3f')} | {r['setting'].replace('|', '/')} |")
    text = "\n".join(lines) + "\n"
    if notes:
        text += "\nNotes:\n\n" + "\n".join(f"- {n}" for n in notes) + "\n"
    return text


def read_rows(path):
    """The rows of an earlier run's rd.csv, typed as this run's rows (empty cells -> None)."""
    types = dict(bpv=float, budget=int, bytes=int, abpv=float, psnr=float, enc=float, dec=float)
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            rows.append({k: (r.get(k) or "") if k in ("volume", "codec", "setting")
                         else (types[k](r[k]) if r.get(k) else None) for k in ROW_KEYS})
    return rows


def plot(rows, outdir, peaks):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("rd_benchmark: python3-matplotlib missing: no plots", file=sys.stderr)
        return []
    written = []
    for vol in sorted({r["volume"] for r in rows}):
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        for codec in CODECS:
            pts = sorted((r["abpv"], r["psnr"]) for r in rows
                         if r["volume"] == vol and r["codec"] == codec and r["psnr"] is not None)
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=codec)
        ax.set_xscale("log", base=2)
        budgets = sorted({r["bpv"] for r in rows if r["volume"] == vol})
        for b in budgets:
            ax.axvline(b, color="gray", ls=":", lw=0.8)
        ax.set_xticks(budgets)
        ax.set_xticklabels([f"{b:g}" for b in budgets])
        ax.set_xlabel("bits per voxel (whole file)")
        ax.set_ylabel(f"PSNR (dB, peak {peaks[vol]:g})" if vol in peaks else "PSNR (dB)")
        ax.set_title(f"{vol}: PSNR vs rate")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fn = os.path.join(outdir, f"rd_{os.path.splitext(vol)[0]}.png")
        fig.tight_layout()
        fig.savefig(fn, dpi=110)
        plt.close(fig)
        written.append(fn)
    return written


# -------------------------------------------------------------------------------------------------------- main

def list_volumes(data):
    """The default volumes: every *.nrrd and every dicom-* series directory in `data`, sorted."""
    return sorted(f for f in os.listdir(data)
                  if f.endswith(".nrrd") or (f.startswith("dicom-") and os.path.isdir(os.path.join(data, f))))


def load_volume(vpath, dcv, out):
    """The (z, y, x) array of a *.nrrd file or a DICOM series directory. A series is given to dcv as the
    directory itself (its DICOM attributes count in the file); the peers and the error measures get it as
    dcv reads it (Hounsfield units), via `dcv convert` into out/NAME.nrrd."""
    if not os.path.isdir(vpath):
        return read_nrrd(vpath)
    nrrd = os.path.join(out, os.path.basename(os.path.normpath(vpath)) + ".nrrd")
    run([dcv, "convert", vpath, nrrd, "-f", "-q"])
    return read_nrrd(nrrd)


def volume_info(vname, vol):
    """(PSNR peak, note or None) for a volume."""
    if vol.dtype == np.uint8:
        return 255.0, None
    lo, hi = vol.min(), vol.max()
    peak = float(hi) - float(lo)
    s = peer_samples(vol)
    if s is None:
        return peak, f"{vname} is {vol.dtype} ({lo:g}..{hi:g}): dcv only (peers need integers), PSNR peak = {peak:g}"
    deps = []
    for name, depths in (("OpenJPEG", OPJ_DEPTHS), ("x265", VIDEO_DEPTHS), ("AV1", VIDEO_DEPTHS)):
        d, sh = codec_depth(s["bits"], depths)
        deps.append(f"{name} {d}-bit" + (f" after a right shift by {sh} (range needs {s['bits']} bits; decoded "
                                         f"values go to the middle of the dropped interval)" if sh else ""))
    note = (f"{vname} is {vol.dtype} ({lo}..{hi}): PSNR peak = max - min = {peak:g}; the peers code value - min "
            f"(min = {lo}) as {s['bits']}-bit unsigned samples ({', '.join(deps)}), the minimum is added back after "
            f"decoding and PSNR is against the original values")
    if lo != 0:
        note += "; the minimum would be a few bytes of side information, not counted in the peers' bytes"
    return peak, note


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=DEFAULT_DATA, help="folder of the *.nrrd volumes (default ../shared/data)")
    ap.add_argument("--volumes", nargs="+", help="file names in --data (default: all *.nrrd)")
    ap.add_argument("--bpv", nargs="+", type=float, default=DEFAULT_BPVS, help="budgets in bits per voxel")
    ap.add_argument("--codecs", nargs="+", choices=CODECS, default=CODECS)
    ap.add_argument("--dcv", default=os.path.join(REPO, "build", "tools", "dcv", "dcv"))
    ap.add_argument("--out", default=os.path.join(REPO, "build", "rd"), help="output folder (default build/rd)")
    ap.add_argument("--merge", nargs="+", metavar="CSV", default=[],
                    help="rd.csv files of earlier runs: their rows are combined with this run's (this run wins for "
                         "the same volume, bpv and codec; a later CSV wins over an earlier one) in the table, CSV "
                         "and plots")
    ap.add_argument("--av1-container", choices=["obu", "ivf"], default="obu",
                    help="aomenc output: obu (Section 5 low-overhead stream, default) or ivf (+32 B +12 B/frame)")
    ap.add_argument("--keep", action="store_true", help="keep the work folders")
    args = ap.parse_args()

    notes = []
    merged = []
    for fn in args.merge:  # read first: a bad path should fail before the long run
        merged.append((fn, read_rows(fn)))
    # tools
    missing = []
    if "dcv" in args.codecs and not (os.path.isfile(args.dcv) and os.access(args.dcv, os.X_OK)):
        missing.append(f"dcv ({args.dcv}: build the project first)")
    for codec in args.codecs:
        for t in TOOLS.get(codec, []):
            if shutil.which(t) is None and not any(t in m for m in missing):
                missing.append(f"{t} (apt-get install {APT[t]})")
    if "x265" in args.codecs and shutil.which("ffmpeg") is None:
        notes.append("ffmpeg missing (apt-get install ffmpeg): x265 PSNR is from its --recon output, no decode time "
                     "(and no x265 above 8 bits)")
    if missing:
        print("rd_benchmark: MISSING TOOLS: " + "; ".join(missing), file=sys.stderr)
        notes.append("missing tools, their codecs are skipped: " + "; ".join(missing))
    usable = [c for c in args.codecs
              if (c != "dcv" or not any(m.startswith("dcv") for m in missing))
              and all(shutil.which(t) for t in TOOLS.get(c, []))]

    vols = args.volumes or list_volumes(args.data)
    os.makedirs(args.out, exist_ok=True)
    ctx = {"dcv": args.dcv, "av1_container": args.av1_container}
    rows = []
    peaks = {}
    for vname in vols:
        vpath = os.path.join(args.data, vname)
        vol = load_volume(vpath, args.dcv, args.out)
        ctx["peak"], vnote = volume_info(vname, vol)
        peaks[vname] = ctx["peak"]
        ctx["samples"] = peer_samples(vol)
        if vnote:
            notes.append(vnote)
        for bpv in args.bpv:
            budget = int(math.floor(bpv * vol.size / 8))
            for codec in usable:
                if codec != "dcv" and ctx["samples"] is None:
                    continue
                work = tempfile.mkdtemp(prefix=f"{os.path.splitext(vname)[0]}_{bpv:g}_{codec}_",
                                        dir=args.out)
                t0 = time.perf_counter()
                try:
                    res = CODEC_FUNCS[codec](vol, vpath, budget, bpv, work, ctx)
                except Exception as e:  # report and carry on
                    res = dict(bytes=None, psnr=None, enc=None, dec=None, setting=f"ERROR: {e}".replace("\n", " "))
                if not args.keep:
                    shutil.rmtree(work, ignore_errors=True)
                row = dict(volume=vname, bpv=bpv, budget=budget, codec=codec, bytes=res["bytes"],
                           abpv=None if res["bytes"] is None else res["bytes"] * 8.0 / vol.size,
                           psnr=res["psnr"], enc=res["enc"], dec=res["dec"], setting=res["setting"])
                rows.append(row)
                print(f"[{time.perf_counter() - t0:7.1f} s search] {vname} bpv={bpv:g} B={budget} {codec}: "
                      f"bytes={row['bytes']} PSNR={fmt(row['psnr'], '.3f')} ({row['setting']})",
                      file=sys.stderr, flush=True)

    if merged:
        # earlier runs first, so that a later CSV and then this run replace their rows
        table = {}
        for fn, mrows in merged:
            for r in mrows:
                table[(r["volume"], r["bpv"], r["codec"])] = r
        replaced = sum((r["volume"], r["bpv"], r["codec"]) in table for r in rows)
        taken = len(table) - replaced
        for r in rows:
            table[(r["volume"], r["bpv"], r["codec"])] = r
        notes.append(f"{taken} rows merged from {', '.join(fn for fn, _ in merged)} ({replaced} more replaced by "
                     f"this run's rows); their encode/decode times are from those runs")
        rows = list(table.values())
        # volume notes and PSNR peaks of the volumes that only come from the merged rows
        for vname in sorted({r["volume"] for r in rows} - set(peaks)):
            vpath = os.path.join(args.data, vname)
            if os.path.isfile(vpath):
                peaks[vname], vnote = volume_info(vname, read_nrrd(vpath))
                if vnote:
                    notes.append(vnote)
    order = {c: i for i, c in enumerate(CODECS)}
    rows.sort(key=lambda r: (r["volume"], r["bpv"], order.get(r["codec"], len(CODECS)), r["codec"]))

    notes.append("PSNR: peak 255 for uint8 volumes, max - min of the original for other types, MSE over all voxels; "
                 "budget B = floor(bpv * voxels / 8) bytes, whole output file; each peer: best PSNR among the tried "
                 "settings whose file has <= B bytes; encode/decode seconds are wall-clock of the chosen setting's "
                 "CLI run(s), file I/O included; every tool with its default threading (x265: its thread pool on all "
                 "cores) except the x265 decode, ffmpeg -threads 1.")
    notes.append("x265: padded (edge replication) to a multiple of 8 in x and y and cropped before PSNR; --no-info "
                 "(no encoder-settings SEI); --ctu lowered to 32/16 when a side is < 64/32 (x265 refuses pictures "
                 "smaller than one CTU) or, above 8 bits, when x265 aborts (a crash of Debian's x265 3.5 on some "
                 "10/12-bit picture sizes); above 8 bits --input-depth/--output-depth 10 or 12 without --profile (x265 "
                 "refuses main10/main12 with 4:0:0 input and codes a RExt monochrome stream) and PSNR from the ffmpeg "
                 "decode (Debian's x265 writes an 8-bit --recon for 10/12-bit encodes).")
    notes.append(f"av1: aomenc default 2-pass good-quality mode, output --{args.av1_container}; both "
                 "--end-usage=q (--cq-level searched) and --end-usage=vbr (--target-bitrate searched) are tried, the "
                 "best fitting PSNR is reported; above 8 bits --bit-depth/--input-bit-depth 10 or 12 (12: --profile=2) "
                 "from a 4:2:0 y4m whose flat chroma --monochrome drops.")
    notes.append("j2k: both the 9/7 irreversible (-I) and 5/3 reversible wavelets are searched; the better fitting "
                 "one is reported; above 8 bits the precision is the range's bit depth (raw: -F X,Y,Z,bits,u with "
                 "16-bit little-endian .rawl samples; mosaic: PGM with maxval 2^bits - 1).")
    text = markdown(rows, notes)
    print(text)
    with open(os.path.join(args.out, "rd.md"), "w") as f:
        f.write("# Rate-distortion comparison\n\nCommand: `" + " ".join([os.path.relpath(sys.argv[0], REPO)] +
                                                                       sys.argv[1:]) + "`\n\n" + text)
    with open(os.path.join(args.out, "rd.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=ROW_KEYS)
        w.writeheader()
        w.writerows(rows)
    for fn in plot(rows, args.out, peaks):
        print(f"plot: {os.path.relpath(fn, REPO)}", file=sys.stderr)
    print(f"table: {os.path.relpath(os.path.join(args.out, 'rd.md'), REPO)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
