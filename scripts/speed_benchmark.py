#!/usr/bin/python3
"""Encoding and decoding speed of dcv against its peers on the same volume and byte budget, side by side
in one run: the figures of docs/benchmarks.md.

Usage: /usr/bin/python3 scripts/speed_benchmark.py [--volume norm-256.nrrd] [--bpv 0.03125 0.25]
                                                   [--runs 3] [--work DIR]
                                                   [--memory dicom-ct-brain-5mm] [--memory-bpv 0.125]

For each rate R (budget B = floor(R x voxels / 8) bytes):
  encode  `dcv compress VOLUME --bpv R` against x265 (--preset slower --tune psnr, the slices as the frames
          of a 4:0:0 video) at its best setting whose stream fits B, found by scripts/rd_benchmark.py's search
          (the same peer settings as the rate-distortion table);
  decode  `dcv decompress OUT.dcv OUT.nrrd --no-compression` against `opj_decompress` of OpenJPEG's best
          mosaic of the slices that fits B (rd_benchmark's j2k-mosaic), to a PGM.
and, for the memory target, `dcv compress MEMORY --bpv 0.125` (the 5 mm CT series, a DICOM directory in
--data; `--memory none` skips it) run --runs times alone: its peak resident memory in bytes a voxel.
The settings are searched first, untimed. Then the two commands of a pair run in turn (A B A B ..., after
one untimed pair), each process timed from outside: wall seconds, CPU seconds (user + system) and peak
resident memory from wait4(). The table gives each command's medians and the median of the pairs' wall
ratios dcv / peer with their range: pairs in turn keep the ratio fair while the machine's speed drifts.

Needs python3-numpy (call Debian's /usr/bin/python3), x265, opj_compress and opj_decompress
(libopenjp2-tools), /usr/bin/time (package time) and build/tools/dcv/dcv. Exits 0 with a message when the volume is absent (../shared
is not there). norm-256 at 0.03125 and 0.25 bpv and the memory job: about 10 minutes on 2 cores.
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rd_benchmark as rd  # noqa: E402  (the peers' searches and the NRRD reader, shared)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def timed(command, log):
    """(wall s, CPU s, peak MiB) of one run of `command`; its output goes to the file `log`. The peak is
    what /usr/bin/time reports of the command itself: a process forked from this one would count this
    one's memory (the volume) in its own peak."""
    peak_file = log + ".peak"
    with open(log, "wb") as out:
        start = time.perf_counter()
        child = subprocess.Popen(["/usr/bin/time", "-f", "%M", "-o", peak_file] + command, stdin=subprocess.DEVNULL,
                                 stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        with open(log, "rb") as f:
            raise SystemExit(f"speed_benchmark: {' '.join(command)} failed ({code}):\n"
                             f"{f.read().decode(errors='replace')[-800:]}")
    with open(peak_file) as f:
        peak = float(f.read().split()[-1]) / 1024.0  # KiB
    return wall, usage.ru_utime + usage.ru_stime, peak


def pairs(ours, peer, runs, work):
    """Runs the two commands in turn (one untimed pair first); returns their runs and the wall ratios."""
    a, b = [], []
    for i in range(runs + 1):
        ra = timed(ours, os.path.join(work, "ours.log"))
        rb = timed(peer, os.path.join(work, "peer.log"))
        if i > 0:
            a.append(ra)
            b.append(rb)
    return a, b, [x[0] / y[0] for x, y in zip(a, b)]


def median(runs, k):
    return statistics.median(r[k] for r in runs)


def row(volume, bpv, job, peer, a, b, ratios):
    return (f"| {volume} | {bpv:g} | {job} | {median(a, 0):.3f} | {median(a, 1):.3f} | {median(a, 2):.0f} | {peer} | "
            f"{median(b, 0):.3f} | {median(b, 1):.3f} | {median(b, 2):.0f} | **{statistics.median(ratios):.2f}** "
            f"({min(ratios):.2f} to {max(ratios):.2f}) |")


def voxels_of(dcv, path):
    """The voxel count of a .dcv file, from `dcv info`'s size line."""
    info = subprocess.run([dcv, "info", path], capture_output=True, text=True, check=True).stdout
    for line in info.splitlines():
        if line.startswith("size:"):
            x, y, z = (int(n) for n in line.split()[1:4])
            return x * y * z
    raise SystemExit(f"speed_benchmark: no size in `dcv info {path}`")


def memory_job(args, work):
    """The row of `dcv compress --memory --bpv --memory-bpv` run --runs times (after one untimed run):
    medians of wall seconds and peak MiB, and the peak in bytes a voxel (median, min to max). None when
    skipped or absent."""
    if args.memory == "none":
        return None
    source = os.path.join(args.data, args.memory)
    if not os.path.exists(source):
        print(f"speed_benchmark: {source} is absent: no memory figure", file=sys.stderr)
        return None
    here = os.path.join(work, "memory")
    os.makedirs(here, exist_ok=True)
    out = os.path.join(here, "out.dcv")
    command = [args.dcv, "compress", source, out, "--bpv", repr(args.memory_bpv), "--force", "-q"]
    print(f"  memory: dcv compress {args.memory} --bpv {args.memory_bpv:g}", file=sys.stderr)
    runs = [timed(command, os.path.join(here, "ours.log")) for _ in range(args.runs + 1)][1:]
    voxels = voxels_of(args.dcv, out)
    per_voxel = [r[2] * 1048576.0 / voxels for r in runs]
    return (f"| {args.memory} | {args.memory_bpv:g} | {voxels} | {median(runs, 0):.3f} | {median(runs, 2):.0f} | "
            f"**{statistics.median(per_voxel):.1f}** ({min(per_voxel):.1f} to {max(per_voxel):.1f}) |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--volume", default="norm-256.nrrd", help="a NRRD of integer voxels in --data")
    ap.add_argument("--data", default=rd.DEFAULT_DATA)
    ap.add_argument("--bpv", type=float, nargs="+", default=[0.03125, 0.25])
    ap.add_argument("--runs", type=int, default=3, help="timed pairs per job (default 3)")
    ap.add_argument("--dcv", default=os.path.join(ROOT, "build", "tools", "dcv", "dcv"))
    ap.add_argument("--work", help="work directory (default: a temporary one, removed at the end)")
    ap.add_argument("--memory", default="dicom-ct-brain-5mm",
                    help="a volume or DICOM series in --data whose peak memory is measured ('none': skipped)")
    ap.add_argument("--memory-bpv", type=float, default=0.125)
    args = ap.parse_args()
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    path = os.path.join(args.data, args.volume)
    if not os.path.isfile(path):
        print(f"speed_benchmark: {path} is absent (../shared/data is needed): nothing measured")
        return 0
    missing = [t for t in ("x265", "opj_compress", "opj_decompress", "/usr/bin/time") if shutil.which(t) is None]
    if missing:
        raise SystemExit(f"speed_benchmark: missing {', '.join(missing)} (apt-get install x265 libopenjp2-tools time)")
    if not os.access(args.dcv, os.X_OK):
        raise SystemExit(f"speed_benchmark: no dcv at {args.dcv} (build the project first: bash scripts/build.sh)")
    volume = rd.read_nrrd(path)
    samples = rd.peer_samples(volume)
    if samples is None:
        raise SystemExit(f"speed_benchmark: {path} has {volume.dtype} voxels; the peers take integers")
    peak, _ = rd.volume_info(args.volume, volume)
    context = {"dcv": args.dcv, "peak": peak, "samples": samples}
    work = args.work or tempfile.mkdtemp(prefix="dcv-speed-")
    os.makedirs(work, exist_ok=True)
    lines = []
    try:
        for bpv in args.bpv:
            budget = int(bpv * volume.size / 8)
            here = os.path.join(work, f"{bpv:g}")
            os.makedirs(here, exist_ok=True)
            print(f"{args.volume} at {bpv:g} bpv ({budget} bytes): searching the peers' settings", file=sys.stderr)
            x265 = rd.codec_x265(volume, path, budget, bpv, here, context)
            mosaic = rd.codec_j2k_mosaic(volume, path, budget, bpv, here, context)
            for name, best in (("x265", x265), ("OpenJPEG", mosaic)):
                if best.get("command") is None:
                    raise SystemExit(f"speed_benchmark: {name} has no setting within {budget} bytes: {best['setting']}")
            dcv = os.path.join(here, "out.dcv")
            compress = [args.dcv, "compress", path, dcv, "--bpv", repr(bpv), "--force", "-q"]
            print(f"  encode: dcv against x265 {x265['setting'].split(';')[0]} ({x265['bytes']} bytes)",
                  file=sys.stderr)
            a, b, ratios = pairs(compress, x265["command"], args.runs, here)
            lines.append(row(args.volume, bpv, "encode", f"x265 {x265['setting'].split(';')[0]}", a, b, ratios))
            # OpenJPEG's best codestream again (the search keeps none), and dcv's own file of this rate.
            rd.run(mosaic["command"])
            codestream = mosaic["command"][mosaic["command"].index("-o") + 1]
            decompress = [args.dcv, "decompress", dcv, os.path.join(here, "dec.nrrd"), "--no-compression", "--force",
                          "-q"]
            print(f"  decode: dcv ({os.path.getsize(dcv)} bytes) against opj_decompress "
                  f"({os.path.getsize(codestream)} bytes)", file=sys.stderr)
            a, b, ratios = pairs(decompress, ["opj_decompress", "-i", codestream, "-o", os.path.join(here, "dec.pgm")],
                                 args.runs, here)
            setting = mosaic["setting"].split(";")[0]
            lines.append(row(args.volume, bpv, "decode", f"opj_decompress ({setting})", a, b, ratios))
        memory = memory_job(args, work)
    finally:
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)
    print(f"{args.runs} pairs a job, medians; ratio: dcv's wall time over the peer's, median (min to max) of the pairs\n")
    print("| volume | bpv | job | dcv wall s | dcv CPU s | dcv peak MiB | peer | peer wall s | peer CPU s | "
          "peer peak MiB | wall ratio |")
    print("|---|---:|---|---:|---:|---:|---|---:|---:|---:|---|")
    for line in lines:
        print(line)
    if memory:
        print("\n| volume | bpv | voxels | dcv wall s | dcv peak MiB | bytes a voxel |")
        print("|---|---:|---:|---:|---:|---|")
        print(memory)
    return 0


if __name__ == "__main__":
    sys.exit(main())
