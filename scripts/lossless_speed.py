#!/usr/bin/python3
"""Speed of the bounded-error layer against CharLS (JPEG-LS), on the same samples in memory, in turn.

For every volume, its samples as scripts/lossless_benchmark.py gives them to the peers (uint8, or value - min
at 16 bits) are written once as raw; then, --runs times, in turn:
  dcv     build/benchmark/dcvBoundedBenchmark: dcv::EncodeBoundedLayer and dcv::DecodeBoundedLayer on the
          volume in memory (--threads, default 0: one per core), checked against the input
  charls  build/benchmark/dcvCharlsPeer: CharLS's encoder and decoder on every z slice (one thread)
Each program times its library calls only (no file reading or writing). The table gives each codec's
median seconds, their ratio (dcv / CharLS) per run as the median and the range over the runs, and the
sizes; both programs print seconds, bytes and the thread count, the script checks nothing else.

Example (the figures of docs/benchmarks.md, "Lossless and near-lossless"):
  scripts/lossless_speed.py --volumes norm-256.nrrd --runs 7
  scripts/lossless_speed.py --volumes norm-256.nrrd avg152t1.nrrd --bounds 0 2 --threads 1
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rd_benchmark as rd  # noqa: E402  (the volume reading and the peers' samples are shared with it)

REPO = rd.REPO


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=rd.TIMEOUT)
    if p.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.strip()[-600:]}")
    return dict(line.split() for line in p.stdout.splitlines())


def cpu_name():
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        return "unknown CPU"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=rd.DEFAULT_DATA, help="folder of the volumes (default ../shared/data)")
    ap.add_argument("--volumes", nargs="+", default=["norm-256.nrrd"], help="names in --data (norm-256.nrrd)")
    ap.add_argument("--bounds", nargs="+", type=int, default=[0], help="NEAR values (default 0: lossless)")
    ap.add_argument("--runs", type=int, default=5, help="pairs per volume and bound (default 5)")
    ap.add_argument("--threads", type=int, default=0, help="dcv's threads (default 0: one per core)")
    ap.add_argument("--build", default=os.path.join(REPO, "build"), help="the build folder (build)")
    args = ap.parse_args()
    dcv = os.path.join(args.build, "benchmark", "dcvBoundedBenchmark")
    charls = os.path.join(args.build, "benchmark", "dcvCharlsPeer")
    for exe in (dcv, charls):
        if not os.access(exe, os.X_OK):
            sys.exit(f"lossless_speed: {exe} missing (build the project; dcvCharlsPeer needs libcharls-dev)")
    print(f"CPU: {cpu_name()}, {os.cpu_count()} cores; dcv threads {args.threads or 'one per core'}; CharLS one thread; {args.runs} pairs")
    print("| volume | NEAR | dcv bytes | CharLS bytes | dcv encode s | CharLS encode s | encode ratio (range) "
          "| dcv decode s | CharLS decode s | decode ratio (range) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="lossless_speed_") as work:
        for vname in args.volumes:
            vol = rd.load_volume(os.path.join(args.data, vname), os.path.join(REPO, "build", "tools", "dcv", "dcv"),
                                 work)
            s = rd.peer_samples(vol)
            if s is None or s["bits"] > 16:
                print(f"lossless_speed: {vname}: not a volume CharLS can code (16 bits at most)", file=sys.stderr)
                continue
            cv = rd.coded(s, 8 if s["bits"] <= 8 else 16, 0)
            z, y, x = cv.shape
            raw, out = os.path.join(work, "in.raw"), os.path.join(work, "out.raw")
            cv.tofile(raw)
            dims = [str(x), str(y), str(z), str(s["bits"])]
            for near in args.bounds:
                d, c = [], []
                for _ in range(args.runs):
                    d.append(run([dcv, raw] + dims + [str(near), str(args.threads)]))
                    c.append(run([charls, raw] + dims + [str(near), out]))

                def med(rows, key):
                    return statistics.median(float(r[key]) for r in rows)

                def ratios(key):
                    r = [float(a[key]) / float(b[key]) for a, b in zip(d, c)]
                    return f"{statistics.median(r):.2f} ({min(r):.2f}-{max(r):.2f})"

                print(f"| {vname} | {near} | {d[0]['bytes']} | {c[0]['bytes']} | {med(d, 'encode_seconds'):.3f} | "
                      f"{med(c, 'encode_seconds'):.3f} | {ratios('encode_seconds')} | {med(d, 'decode_seconds'):.3f} | "
                      f"{med(c, 'decode_seconds'):.3f} | {ratios('decode_seconds')} |", flush=True)


if __name__ == "__main__":
    main()
