#!/usr/bin/python3
"""Tables for REPORT.md from results.csv: per volume and rate, the single layers, the best split of each
(order, layer), and the gain of the best split over the best single layer and over x265 alone."""
import csv
import os
from collections import defaultdict

HERE = os.path.dirname(os.path.abspath(__file__))
_all = list(csv.DictReader(open(os.environ.get("LAYER_SPLIT_CSV", "layer-split-results.csv"))))
_last = {}
for r in _all:  # a re-run's row replaces the earlier one of the same volume, rate, order, layer and share
    _last[(r["volume"], r["bpv"], r["order"], r["layer"], r["share_target"])] = r
rows = list(_last.values())
runs = defaultdict(list)
order = []
for r in rows:
    k = (r["volume"], float(r["bpv"]))
    if k not in runs:
        order.append(k)
    runs[k].append(r)


def f(x):
    return float(x) if x not in ("", None, "None") else None


def cell(r):
    return "-" if r is None else f"{f(r['psnr']):.2f}"


out = []
out.append("| volume | bpv | B | x265 alone | j2kz alone | points alone | product (real file) | best pf x265 (s) | "
           "best pf j2kz (s) | best tf x265 (s) | best tf j2kz (s) | best split - best single | best split - x265 |")
out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
detail = []
for k in order:
    rs = [r for r in runs[k] if f(r["psnr"]) is not None]
    single = {}
    for r in rs:
        if r["order"] == "alone":
            if r["layer"] in ("x265", "j2kz", "points"):
                single[r["layer"]] = r
        if r["order"] == "product":
            single["product"] = r
    best = {}
    for r in rs:
        if r["order"] in ("pf", "tf") and r["layer"] in ("x265", "j2kz"):
            key = (r["order"], r["layer"])
            if key not in best or f(r["psnr"]) > f(best[key]["psnr"]):
                best[key] = r
    bs = max((f(r["psnr"]) for r in single.values()), default=None)
    bsplit = max((f(r["psnr"]) for r in best.values()), default=None)
    x = single.get("x265")

    def bc(key):
        r = best.get(key)
        return "-" if r is None else f"{f(r['psnr']):.2f} ({float(r['share_actual']):.2f})"

    g1 = "-" if bs is None or bsplit is None else f"{bsplit - bs:+.2f}"
    g2 = "-" if x is None or bsplit is None else f"{bsplit - f(x['psnr']):+.2f}"
    out.append(f"| {k[0].replace('.nrrd', '')} | {k[1]:g} | {rs[0]['budget'] if rs else ''} | {cell(x)} | "
               f"{cell(single.get('j2kz'))} | {cell(single.get('points'))} | {cell(single.get('product'))} | "
               f"{bc(('pf', 'x265'))} | {bc(('pf', 'j2kz'))} | {bc(('tf', 'x265'))} | {bc(('tf', 'j2kz'))} | "
               f"{g1} | {g2} |")
    # share curves
    for o in ("pf", "tf"):
        for layer in ("x265", "j2kz"):
            pts = [(float(r["share_actual"]), f(r["psnr"])) for r in rs if r["order"] == o and r["layer"] == layer]
            base = single.get(layer)
            if pts:
                detail.append(f"| {k[0].replace('.nrrd', '')} | {k[1]:g} | {o} {layer} | "
                              + (f"{f(base['psnr']):.2f}" if base else "-") + " | "
                              + " ".join(f"{s:.2f}:{p:.2f}" for s, p in sorted(pts)) + " |")
print("\n".join(out))
print()
print("| volume | bpv | order layer | layer alone (s=0) | share:PSNR |")
print("|---|---|---|---|---|")
print("\n".join(detail))
