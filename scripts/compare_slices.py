#!/usr/bin/python3
"""Decoded slices beside the original: dcv and x265 at the same byte budget, axial and coronal, with their
errors, in one PNG. What PSNR hides (ringing, streaks across thick slices, blocks, the spline's creases)
shows here.

Usage: /usr/bin/python3 scripts/compare_slices.py VOLUME --bpv R --out OUT.png [--dcv build/tools/dcv/dcv]
                                                  [--axial Z] [--coronal Y] [--window LO HI]

VOLUME is an NRRD file or a DICOM series directory (read as `dcv convert` reads it). The budget is
floor(R x voxels / 8) bytes for the whole file: dcv is `dcv compress VOLUME --bpv R`, x265 its best setting
whose stream fits the budget, searched as scripts/rd_benchmark.py searches it (`--preset slower --tune
psnr`, the slices as the frames of a 4:0:0 video). Rows: the axial slice (default: the middle one) and the
coronal one (default: the middle row); columns: the original, dcv, x265, |dcv - original| and |x265 -
original| (the errors on one common scale, white = the larger of the two maxima). Grey levels: --window, or
the volume's 0.5 and 99.5 percentiles. The titles give each codec's bytes and PSNR.

Needs python3-numpy and python3-matplotlib (call Debian's /usr/bin/python3), x265 and ffmpeg.
"""
import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rd_benchmark as rd  # noqa: E402  (the NRRD reader, the peers' samples and the x265 search)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("volume")
    ap.add_argument("--bpv", type=float, required=True)
    ap.add_argument("--out", required=True, help="the PNG to write")
    ap.add_argument("--dcv", default=os.path.join(ROOT, "build", "tools", "dcv", "dcv"))
    ap.add_argument("--axial", type=int, help="slice index z (default: the middle)")
    ap.add_argument("--coronal", type=int, help="row index y (default: the middle)")
    ap.add_argument("--window", type=float, nargs=2, metavar=("LO", "HI"))
    args = ap.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("compare_slices: python3-matplotlib is needed (apt-get install python3-matplotlib)")
    for tool in ("x265", "ffmpeg"):
        if shutil.which(tool) is None:
            sys.exit(f"compare_slices: {tool} is needed (apt-get install {tool})")
    if not os.path.exists(args.volume):
        sys.exit(f"compare_slices: {args.volume}: no such file or directory")

    work = tempfile.mkdtemp(prefix="compare_slices_")
    try:
        path = args.volume
        if os.path.isdir(path):
            path = os.path.join(work, "volume.nrrd")
            rd.run([args.dcv, "convert", args.volume, path, "-f", "-q"])
        vol = rd.read_nrrd(path)
        spacing = nrrd_spacing(path)
        peak, _ = rd.volume_info(os.path.basename(args.volume), vol)
        budget = int(math.floor(args.bpv * vol.size / 8))

        out = os.path.join(work, "out.dcv")
        dec = os.path.join(work, "dec.nrrd")
        rd.run([args.dcv, "compress", args.volume, out, "--bpv", repr(args.bpv), "-f", "-q"])
        rd.run([args.dcv, "decompress", out, dec, "-f", "-q"])
        dcv = rd.read_nrrd(dec).astype(np.float64)
        dcv_bytes = os.path.getsize(out)

        samples = rd.peer_samples(vol)
        if samples is None:
            sys.exit("compare_slices: x265 takes integer volumes only")
        ctx = {"samples": samples, "peak": peak}
        best = rd.codec_x265(vol, path, budget, args.bpv, work, ctx)
        if best.get("recon") is None:
            sys.exit(f"compare_slices: no x265 setting fits {budget} bytes ({best['setting']})")
        depth, shift = rd.codec_depth(samples["bits"], rd.VIDEO_DEPTHS)
        x265 = rd.restore(samples, best["recon"], shift).astype(np.float64)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    original = vol.astype(np.float64)
    z = args.axial if args.axial is not None else vol.shape[0] // 2
    y = args.coronal if args.coronal is not None else vol.shape[1] // 2
    lo, hi = args.window if args.window else np.percentile(original, [0.5, 99.5])
    views = [("axial z=%d" % z, lambda v: v[z]), ("coronal y=%d" % y, lambda v: v[:, y, :])]
    errors = [np.abs(dcv - original), np.abs(x265 - original)]
    emax = max(float(e.max()) for e in errors) or 1.0
    titles = ["original",
              f"dcv: {dcv_bytes} B, {rd.psnr(vol, dcv, peak):.2f} dB",
              f"x265: {best['bytes']} B, {best['psnr']:.2f} dB",
              "|dcv - original|", "|x265 - original|"]
    # The coronal view in physical proportions (spacing z over x): slices may be much thicker than pixels.
    fig, axes = plt.subplots(2, 5, figsize=(17, 7.5))
    for row, (name, cut) in enumerate(views):
        aspect = 1.0 if row == 0 else spacing[2] / spacing[0]
        for col, (volume, title) in enumerate(zip([original, dcv, x265] + errors, titles)):
            ax = axes[row, col]
            if col < 3:
                ax.imshow(cut(volume), cmap="gray", vmin=lo, vmax=hi, aspect=aspect, interpolation="nearest",
                          origin="upper" if row == 0 else "lower")
            else:
                ax.imshow(cut(volume), cmap="gray", vmin=0, vmax=emax, aspect=aspect, interpolation="nearest",
                          origin="upper" if row == 0 else "lower")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(title if row == 0 else name, fontsize=10)
    fig.suptitle(f"{os.path.basename(args.volume.rstrip('/'))} at {args.bpv:g} bits per voxel "
                 f"(budget {budget} bytes); errors white at {emax:.0f}")
    fig.tight_layout()
    fig.savefig(args.out, dpi=80)
    print(f"Wrote {args.out}: dcv {dcv_bytes} B {rd.psnr(vol, dcv, peak):.3f} dB, "
          f"x265 {best['bytes']} B {best['psnr']:.3f} dB ({best['setting']})")


def nrrd_spacing(path):
    """The spacing (x, y, z) of an NRRD file from its header, (1, 1, 1) when it names none."""
    spacing = [1.0, 1.0, 1.0]
    with open(path, "rb") as f:
        for raw in f:
            line = raw.decode("latin-1").strip()
            if not line:
                break
            if line.startswith("space directions:"):
                vectors = line.split(":", 1)[1].split()
                for i, v in enumerate(vectors[:3]):
                    parts = [abs(float(c)) for c in v.strip("()").split(",")]
                    spacing[i] = math.sqrt(sum(c * c for c in parts))
            elif line.startswith("spacings:"):
                spacing = [float(c) for c in line.split(":", 1)[1].split()[:3]]
    return spacing


if __name__ == "__main__":
    main()
