#!/usr/bin/python3
"""The 40 dev runs (every volume of ../shared/data at 0.03125, 0.0625, 0.125 and 0.25 bpv) through one
`dcv compress`, and two such sets side by side: what a change to the encoder does to every file.

Usage:
  /usr/bin/python3 scripts/dev_runs.py run OUT.csv [--dcv build/tools/dcv/dcv] [--threads N]
                                       [--volumes NAME ...] [--bpv R ...] [-- EXTRA dcv compress OPTIONS]
  /usr/bin/python3 scripts/dev_runs.py compare BEFORE.csv AFTER.csv

`run` compresses each volume at each rate (`dcv compress VOLUME OUT.dcv --bpv R`), one job at a time, and
writes a row a run: the file's bytes, its PSNR, the wall seconds, the points it holds and its md5, as
`dcv compress` prints them. `compare` prints a Markdown table of the two sets, run by run (the PSNR
difference AFTER - BEFORE, the time ratio AFTER / BEFORE, whether the files are the same), and the
largest loss, the mean difference and the total times. Exits 0 with a message when ../shared/data is
absent.
"""
import argparse
import csv
import hashlib
import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "..", "shared", "data")
RATES = [0.03125, 0.0625, 0.125, 0.25]
FIELDS = ["volume", "bpv", "bytes", "psnr", "seconds", "points", "md5"]


def volumes(names):
    found = sorted(f for f in os.listdir(DATA) if f.endswith(".nrrd"))
    if os.path.isdir(os.path.join(DATA, "dicom-ct-brain-5mm")):
        found.append("dicom-ct-brain-5mm")
    return [f for f in found if not names or f in names or f.replace(".nrrd", "") in names]


def field(pattern, text, what, command):
    m = re.search(pattern, text, re.M)
    if not m:
        raise SystemExit(f"dev_runs: no `{what}` in the output of {' '.join(command)}:\n{text[-800:]}")
    return m.group(1)


def run(args, extra):
    if not os.path.isdir(DATA):
        print(f"dev_runs: {DATA} is absent; nothing to run")
        return
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for volume in volumes(args.volumes):
            for rate in args.bpv:
                out = os.path.join(work, f"{volume}-{rate}.dcv")
                command = [args.dcv, "compress", os.path.join(DATA, volume), out, "--bpv", str(rate)] + extra
                if args.threads:
                    command += ["--threads", str(args.threads)]
                start = time.perf_counter()
                done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                wall = time.perf_counter() - start
                if done.returncode != 0:
                    raise SystemExit(f"dev_runs: {' '.join(command)} failed ({done.returncode}):\n{done.stdout[-800:]}")
                text = done.stdout
                if args.logs:
                    os.makedirs(args.logs, exist_ok=True)
                    with open(os.path.join(args.logs, f"{volume.replace('.nrrd', '')}-{rate}.log"), "w") as f:
                        f.write(text)
                with open(out, "rb") as f:
                    md5 = hashlib.md5(f.read()).hexdigest()
                row = {"volume": volume.replace(".nrrd", ""), "bpv": rate,
                       "bytes": os.path.getsize(out),
                       "psnr": field(r"^PSNR: ([^ ]+)", text, "PSNR", command),
                       "seconds": f"{wall:.2f}",
                       "points": field(r"^points: (\d+)", text, "points", command), "md5": md5}
                os.remove(out)
                rows.append(row)
                print(" ".join(str(row[k]) for k in FIELDS), flush=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        w.writerows(rows)


def compare(args):
    def load(path):
        with open(path) as f:
            return {(r["volume"], float(r["bpv"])): r for r in csv.DictReader(f)}

    a, b = load(args.before), load(args.after)
    keys = [k for k in a if k in b]
    print("| volume | bpv | bytes before | bytes after | PSNR before | PSNR after | dB | points before | "
          "points after | s before | s after | time | file |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    diffs, ta, tb = [], 0.0, 0.0
    for k in keys:
        x, y = a[k], b[k]
        px, py = float(x["psnr"].replace("inf", "999")), float(y["psnr"].replace("inf", "999"))
        d = py - px
        diffs.append((d, k))
        ta += float(x["seconds"])
        tb += float(y["seconds"])
        same = "same" if x["md5"] == y["md5"] else "changed"
        print(f"| {k[0]} | {k[1]:g} | {x['bytes']} | {y['bytes']} | {px:.3f} | {py:.3f} | {d:+.3f} | {x['points']} | "
              f"{y['points']} | {float(x['seconds']):.1f} | {float(y['seconds']):.1f} | "
              f"{float(y['seconds']) / max(1e-9, float(x['seconds'])):.2f} | {same} |")
    if not diffs:
        return
    worst = min(diffs)
    print(f"\n{len(keys)} runs; largest loss {worst[0]:+.3f} dB ({worst[1][0]} at {worst[1][1]:g} bpv); "
          f"mean {sum(d for d, _ in diffs) / len(diffs):+.4f} dB; "
          f"files the same {sum(a[k]['md5'] == b[k]['md5'] for k in keys)}; "
          f"total seconds {ta:.1f} -> {tb:.1f} ({tb / max(ta, 1e-9):.3f})")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run")
    r.add_argument("out")
    r.add_argument("--dcv", default=os.path.join(ROOT, "build", "tools", "dcv", "dcv"))
    r.add_argument("--threads", type=int, default=0)
    r.add_argument("--logs", help="a directory for each run's output")
    r.add_argument("--volumes", nargs="*", default=[])
    r.add_argument("--bpv", nargs="*", type=float, default=RATES)
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    args = parser.parse_args(argv)
    if args.command == "run":
        run(args, extra)
    else:
        compare(args)


if __name__ == "__main__":
    main()
