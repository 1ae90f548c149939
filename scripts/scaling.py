#!/usr/bin/env python3
"""How the encoder's time and memory grow with the volume: `dcv compress --bpv R` on three sizes of brain
MR, with what a 512 x 512 x 1000 series would need by the law between the two largest.

Usage: /usr/bin/python3 scripts/scaling.py [--rates 0.03125 0.125] [--work DIR]

The sizes: flair-mr (2.8 M voxels) and norm-256 (16.8 M) from ../shared/data, and norm-256 resampled
linearly to twice its first two axes (512 x 512 x 256, 67.1 M voxels, spacing 0.5 x 0.5 x 1 mm: finer
pixels than slices, as in a CT series), written to the work directory (default a temporary one, removed
at the end). One process per run, timed from outside (/usr/bin/time: wall seconds and the peak resident
memory). Prints a Markdown table (build output on stderr), with the peak against the encoder's memory
model (dcv::EncodingMemory, which `dcv compress` checks before it starts, from the constants of
include/dcvEncoder.h; a peak above it is reported on stderr). Needs python3-numpy (Debian's
/usr/bin/python3) and /usr/bin/time (Debian's package time); exits 0 with a message when ../shared/data
is absent. Takes about 5 minutes on 2 cores.
"""
import argparse
import math
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rd_benchmark as rd  # noqa: E402  (the NRRD reader, shared)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "..", "shared", "data")
DCV = os.path.join(ROOT, "build", "tools", "dcv", "dcv")


def read_uint8(path):
    """The voxels (z, y, x) of a NRRD of uint8 voxels (rd_benchmark's reader)."""
    volume = rd.read_nrrd(path)
    if volume.dtype != np.uint8:
        raise SystemExit(f"scaling.py: {path}: uint8 voxels expected, got {volume.dtype}")
    return volume


def upsample_in_plane(volume):
    """Linear interpolation to twice the rows and columns (the voxel centres of the finer grid)."""
    def axis(v, along):
        n = v.shape[along]
        at = (np.arange(2 * n) + 0.5) / 2.0 - 0.5
        lo = np.clip(np.floor(at).astype(int), 0, n - 1)
        hi = np.clip(lo + 1, 0, n - 1)
        w = np.clip(at - lo, 0.0, 1.0).astype(np.float32)
        shape = [1] * v.ndim
        shape[along] = 2 * n
        w = w.reshape(shape)
        return np.take(v, lo, axis=along) * (1.0 - w) + np.take(v, hi, axis=along) * w

    out = axis(axis(volume.astype(np.float32), 2), 1)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def write_nrrd(path, volume, spacing):
    z, y, x = volume.shape
    header = (f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {x} {y} {z}\n"
              f"spacings: {spacing[0]} {spacing[1]} {spacing[2]}\nencoding: raw\nendian: little\n\n")
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(volume.tobytes())


def found(pattern, text, what):
    match = re.search(pattern, text)
    if not match:
        raise SystemExit(f"scaling.py: no {what} in what dcv printed:\n{text}")
    return match.groups()


def compress(volume, rate, out):
    """(wall s, peak MiB, what won, PSNR dB) of one `dcv compress` run."""
    timed = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", DCV, "compress", volume, out, "--bpv", str(rate),
                            "--force"], capture_output=True, text=True)
    if timed.returncode != 0:
        raise SystemExit(f"scaling.py: dcv compress {volume} --bpv {rate} failed:\n{timed.stderr}")
    wall, peak = found(r"TIME (\S+) (\d+)", timed.stderr, "time")
    points = int(found(r"points: (\d+)", timed.stdout, "point count")[0])
    layer = found(r"residual layer: (\S+)", timed.stdout, "residual layer")[0] != "none"
    psnr = float(found(r"PSNR: (\S+) dB", timed.stdout, "PSNR")[0])
    kept = "corners' layer" if layer and points == 8 else f"{points} points" + (" and a layer" if layer else "")
    return float(wall), int(peak) / 1024.0, kept, psnr


def model(voxels, rate):
    """dcv::EncodingMemory of `dcv compress --bpv rate` (the residual layer on), in MiB, from the constants of
    include/dcvEncoder.h."""
    with open(os.path.join(ROOT, "include", "dcvEncoder.h")) as f:
        header = f.read()
    constant = {name: float(found(rf"constexpr double {name} = ([0-9.]+);", header, name)[0])
                for name in ("EncodingBytesPerVoxelWithResidualLayer", "EncodingBytesPerPoint")}
    points = max(8.0, min(voxels, rate * voxels / 8.0))
    return (voxels * constant["EncodingBytesPerVoxelWithResidualLayer"] +
            points * constant["EncodingBytesPerPoint"]) / 2.0 ** 20


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", nargs="+", type=float, default=[0.03125, 0.125])
    parser.add_argument("--work", help="directory for the resampled volume and the .dcv files")
    args = parser.parse_args()
    if not os.path.isdir(DATA):
        print(f"scaling.py: no data directory at {DATA}; nothing to measure", file=sys.stderr)
        return 0
    if not os.access("/usr/bin/time", os.X_OK):
        raise SystemExit("scaling.py: /usr/bin/time is needed (apt-get install time)")
    if subprocess.run(["cmake", "--build", os.path.join(ROOT, "build"), "--target", "dcv"],
                      stdout=sys.stderr).returncode != 0:
        raise SystemExit("scaling.py: dcv could not be built in build/ (configure it with scripts/build.sh)")
    if args.work:
        os.makedirs(args.work, exist_ok=True)
        return measure(args.rates, args.work)
    with tempfile.TemporaryDirectory(prefix="dcv-scaling-") as work:
        return measure(args.rates, work)


def measure(rates, work):
    norm = read_uint8(os.path.join(DATA, "norm-256.nrrd"))
    flair = read_uint8(os.path.join(DATA, "flair-mr.nrrd"))
    large = upsample_in_plane(norm)
    path = os.path.join(work, "norm-512x512x256.nrrd")
    write_nrrd(path, large, (0.5, 0.5, 1.0))
    volumes = [("flair-mr", os.path.join(DATA, "flair-mr.nrrd"), flair.size),
               ("norm-256", os.path.join(DATA, "norm-256.nrrd"), norm.size),
               ("norm-256 at 512 x 512 x 256", path, large.size)]
    del norm, flair, large
    print("| volume | Mvoxels | bpv | wall s | s per Mvoxel | peak MiB | bytes a voxel | model MiB | kept | PSNR dB |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    runs = {}
    for rate in rates:
        for name, path, voxels in volumes:
            wall, peak, kept, psnr = compress(path, rate, os.path.join(work, "out.dcv"))
            runs[(name, rate)] = (voxels, wall, peak)
            bound = model(voxels, rate)
            print(f"| {name} | {voxels / 1e6:.1f} | {rate:g} | {wall:.1f} | {wall / (voxels / 1e6):.2f} | "
                  f"{peak:.0f} | {peak * 1048576 / voxels:.1f} | {bound:.0f} | {kept} | {psnr:.2f} |", flush=True)
            if peak > bound:
                print(f"scaling.py: {name} at {rate:g} bpv peaked at {peak:.0f} MiB, above the memory model's "
                      f"{bound:.0f}", file=sys.stderr)
    # 512 x 512 x 1000 by the law between the two largest sizes: time ~ voxels^a; memory linear in them.
    target = 512 * 512 * 1000
    print(f"\n512 x 512 x 1000 ({target / 1e6:.0f} M voxels), from the two largest sizes:")
    for rate in rates:
        (v1, t1, m1), (v2, t2, m2) = runs[(volumes[1][0], rate)], runs[(volumes[2][0], rate)]
        a = math.log(t2 / t1) / math.log(v2 / v1)
        per_voxel = (m2 - m1) / (v2 - v1)
        print(f"- {rate:g} bpv: time ~ voxels^{a:.2f}: about {t2 * (target / v2) ** a / 60:.0f} minutes; memory "
              f"{per_voxel * 1048576:.1f} bytes a voxel beyond the smaller: about "
              f"{(m2 + per_voxel * (target - v2)) / 1024:.1f} GiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
