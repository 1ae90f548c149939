#!/usr/bin/python3
"""Can significant points (dcv, points only) and a transform layer (x265 HEVC or JPEG 2000) be partners?

For one volume and one budget B = floor(bpv * voxels / 8) bytes (whole file):

  alone   x265 / j2k      the layer alone on the volume (rd_benchmark's codec_x265 / codec_j2k_<variant> search)
  alone   points          dcv points only, the largest N (best of 3 steps) whose .dcv fits B
  product dcv --bpv       the current product (rate control picks points or corners + JPEG 2000)
  pf      x265 / j2k      points first: points-only .dcv at ~ s*B, residual r = original - spline, the layer codes r
                          in B - points - 16 bytes; decoded = clip(spline + decoded r)
  tf      x265 / j2k      transform first: the layer codes the volume in (1-s)*B - 16 bytes, e = original - decoded,
                          a points-only .dcv of e + offset fills the bytes left; decoded = clip(layer + spline(e))

Every byte is counted: the .dcv file (its container header included), the layer's file as rd_benchmark counts it
(x265 raw HEVC stream, j2k codestream) and 16 bytes of side information (offset/step) for a two-layer file.

Residual samples for x265 (pf): at the bit depth x265 codes the original with (8 for uint8, 12 for the CT),
q = clip(round(r / step) + 2^(d-1)), step in {1, 2} chosen by the lower floor (clip + rounding) MSE.
For j2k (pf): r - min(r) at the bits its range needs (OpenJPEG takes up to 16 bits), exact.

Usage: partner.py VOLUME.nrrd --bpv 0.0625 [--shares 0.05 0.1 ...] [--layers x265 j2k] [--orders pf tf]
Rows are appended to $LAYER_SPLIT_CSV (default layer-split-results.csv in the working directory).
"""
import argparse
import csv
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import rd_benchmark as rd  # noqa: E402
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import j2kz  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
# The dcv to run: $DCV, else the project's build.
DCV = os.environ.get("DCV", os.path.join(os.path.dirname(os.path.dirname(HERE)), "build", "tools", "dcv", "dcv"))
UP_FIRST = True
SIDE = 16  # bytes of side information of a two-layer file (offset, step, layer sizes)
CSV = os.environ.get("LAYER_SPLIT_CSV", "layer-split-results.csv")
FIELDS = ["volume", "bpv", "budget", "order", "layer", "share_target", "points_bytes", "layer_bytes", "side_bytes",
          "total_bytes", "share_actual", "psnr", "points_n", "points_step", "spline_psnr", "layer_setting", "seconds",
          "note"]

# ---------------------------------------------------------------- hook rd_benchmark's psnr to get the decoded volume
ORIG = None
PEAK = None
LOHI = None
HOOK = None  # test (restored layer samples) -> final decoded volume
BEST = {}
_psnr = rd.psnr


def hooked_psnr(ref, test, peak):
    if HOOK is None:
        return _psnr(ref, test, peak)
    final = HOOK(test)
    p = _psnr(ORIG, final, PEAK)
    if p > BEST.get("psnr", -1e9):
        BEST["psnr"] = p
        BEST["final"] = final
    return p


rd.psnr = hooked_psnr
_search_linear = rd.search_linear
ITERS = int(os.environ.get("P49_ITERS", "9"))
rd.search_linear = lambda trial, budget, x0, lo, hi, iters: _search_linear(trial, budget, x0, lo, hi, min(iters, ITERS))


def clipv(a):
    return np.clip(a, LOHI[0], LOHI[1])


def dcv_layer(src, off, budget, work):
    """The product's JPEG 2000 layer (dcv compress --bpv: corners + layer, 9/7 + inter-slice wavelet) on the volume
    in `src` (value + off). Counted bytes = the layer's codestream (dcv info) only: the container, the corners and
    the offset are taken as covered by the 16 side bytes. Returns (res, decoded values - off)."""
    nvox = ORIG.size
    out = os.path.join(work, "layer.dcv")
    dec = os.path.join(work, "layer.nrrd")
    fb = budget + 80
    best = None
    for it in range(5):
        if fb < 100:
            break
        subprocess.run(["nice", "-n", "10", DCV, "compress", src, out, "--bpv", repr(fb * 8.0 / nvox), "-f", "-q"],
                       check=True)
        inf = subprocess.run([DCV, "info", out], stdout=subprocess.PIPE, text=True).stdout
        lay = re.search(r"residual layer: (\d+) bytes", inf)
        pts = int(re.search(r"points: (\d+)", inf).group(1))
        size = os.path.getsize(out)
        cs = int(lay.group(1)) if lay else 0
        counted = cs if pts <= 8 and cs else size  # points chosen: the whole file counts
        if counted <= budget:
            if best is None or counted > best["bytes"]:
                subprocess.run(["nice", "-n", "10", DCV, "decompress", out, dec, "-f", "-q"], check=True)
                v = rd.read_nrrd(dec).astype(np.int64) - off
                best = dict(bytes=counted, setting=f"dcv --bpv {fb * 8.0 / nvox:.5g}: file {size} B, {pts} points, "
                            f"layer codestream {cs} B", final=v)
            if budget - counted < max(8, budget // 100):
                break
        fb -= counted - budget + (2 if counted > budget else -2)
    if best is None:
        return dict(bytes=None, psnr=None, setting="dcv layer does not fit"), None
    return best, best.pop("final")


def run_j2kz(vol_f, budget, work):
    d = tempfile.mkdtemp(prefix="j2kz_", dir=work)
    try:
        res, v = j2kz.code_best(rd, vol_f, budget, d, up_first=UP_FIRST)
    finally:
        shutil.rmtree(d, ignore_errors=True)
    return res, v


def run_layer(layer, samples, budget, hook, work, j2k_variant):
    """Run rd_benchmark's search for `layer` on `samples` within `budget`. Returns (res, final volume)."""
    global HOOK
    HOOK = hook
    BEST.clear()
    ctx = {"peak": PEAK, "samples": samples, "av1_container": "obu"}
    fn = {"x265": rd.codec_x265, "j2k": rd.codec_j2k_comp if j2k_variant == "comp" else rd.codec_j2k_mosaic}[layer]
    d = tempfile.mkdtemp(prefix=f"{layer}_", dir=work)
    try:
        res = fn(ORIG, None, budget, None, d, ctx)
    finally:
        shutil.rmtree(d, ignore_errors=True)
        HOOK = None
    if res.get("bytes") is None:
        return res, None
    final = BEST.get("final")
    if final is None or abs(BEST["psnr"] - res["psnr"]) > 1e-6:
        # the chosen trial is not the best hooked one (e.g. ffmpeg decode != recon): flag it
        res["setting"] += f"; WARNING hooked best {BEST.get('psnr')} != {res['psnr']}"
    return res, final


# ---------------------------------------------------------------------------------------------------- points
def write_nrrd(path, arr):
    t = {np.dtype("uint8"): "unsigned char", np.dtype("int16"): "short", np.dtype("uint16"): "unsigned short"}[
        arr.dtype]
    z, y, x = arr.shape
    with open(path, "wb") as f:
        f.write(f"NRRD0004\ntype: {t}\ndimension: 3\nsizes: {x} {y} {z}\nencoding: raw\nendian: little\n\n".encode())
        f.write(arr.astype(arr.dtype.newbyteorder("<")).tobytes())


def dcv_points(src, n, step, out):
    cmd = [DCV, "compress", src, out, "--points", str(n), "--no-residual-layer", "-f"]
    if step:
        cmd += ["--step", repr(step)]
    p = subprocess.run(["nice", "-n", "10"] + cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        return None
    m = re.search(r"PSNR: ([-\d.inf]+)", p.stdout)
    return dict(bytes=os.path.getsize(out), dcv_psnr=float(m.group(1)) if m else None, n=n, step=step)


def fit_points(src, target, steps, work, nmax):
    """Largest N whose points-only .dcv has <= target bytes, for each step; the best (dcv's own PSNR) wins.
    Returns dict(bytes, n, step, file, dcv_psnr, spline) or None when even 8 points do not fit."""
    best = None
    for step in steps:
        cache = {}

        def f(n):
            if n not in cache:
                out = os.path.join(work, f"p_{step}_{n}.dcv")
                cache[n] = dcv_points(src, n, step, out)
            return cache[n]

        r8 = f(8)
        if r8 is None or r8["bytes"] > target:
            continue
        lo = 8
        hi = None
        n = max(9, int(target / 2.5))
        while hi is None:
            n = min(n, nmax)
            r = f(n)
            if r is not None and r["bytes"] <= target:
                lo = n
                if n >= nmax:
                    break
                n = int(n * 1.6) + 1
            else:
                hi = n
        while hi is not None and hi - lo > max(1, lo // 100):
            mid = (lo + hi) // 2
            r = f(mid)
            if r is not None and r["bytes"] <= target:
                lo = mid
            else:
                hi = mid
        # rate is not strictly monotonic in N: also look at a few N just above lo
        cands = [cache[k] for k in cache if cache[k] is not None and cache[k]["bytes"] <= target]
        r = max(cands, key=lambda c: (c["dcv_psnr"], c["bytes"]))
        r["file"] = os.path.join(work, f"p_{step}_{r['n']}.dcv")
        if best is None or r["dcv_psnr"] > best["dcv_psnr"]:
            best = r
    if best is None:
        return None
    dec = os.path.join(work, "spline.nrrd")
    subprocess.run(["nice", "-n", "10", DCV, "decompress", best["file"], dec, "-f", "-q"], check=True)
    best["spline"] = rd.read_nrrd(dec).astype(np.int64)
    return best


# ------------------------------------------------------------------------------------------------ experiments
def residual_samples_x265(r, depth):
    """(samples dict for rd's x265, step, mid, floor MSE)"""
    mid = 1 << (depth - 1)
    top = (1 << depth) - 1
    best = None
    for step in (1, 2):
        q = np.clip(np.rint(r / step) + mid, 0, top).astype(np.int64)
        floor = float(np.mean((r - (q - mid) * step) ** 2))
        if best is None or floor < best[3]:
            best = (dict(codes=q, offset=0, bits=depth), step, mid, floor)
    return best


def residual_samples_j2k(r):
    lo = int(r.min())
    bits = max(8, int(r.max() - lo).bit_length())
    return dict(codes=r.astype(np.int64) - lo, offset=lo, bits=bits)


def main():
    global ORIG, PEAK, LOHI
    ap = argparse.ArgumentParser()
    ap.add_argument("volume")
    ap.add_argument("--bpv", type=float, required=True)
    ap.add_argument("--shares", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.35, 0.5])
    ap.add_argument("--layers", nargs="+", default=["x265", "j2kz"], help="x265, j2kz (z 9/7 + OpenJPEG, like the product's corners layer), dcvj2k (the product's JPEG 2000 layer via dcv --bpv), j2k (rd_benchmark's OpenJPEG search)")
    ap.add_argument("--orders", nargs="+", default=["alone", "product", "pf", "tf"])
    ap.add_argument("--j2k", default="comp", choices=["comp", "mosaic"])
    ap.add_argument("--pf-steps", type=float, nargs="+", help="dcv --step values tried, points first "
                    "(default 1, 2, 4 times peak/64)")
    ap.add_argument("--tf-steps", type=float, nargs="+", default=[1, 2, 4], help="dcv --step values, transform first")
    ap.add_argument("--keep", action="store_true")
    a = ap.parse_args()

    global UP_FIRST
    UP_FIRST = a.bpv <= 0.125
    vname = os.path.basename(a.volume)
    ORIG = rd.read_nrrd(a.volume)
    PEAK, _ = rd.volume_info(vname, ORIG)
    info = np.iinfo(ORIG.dtype)
    LOHI = (info.min, info.max)
    orig64 = ORIG.astype(np.int64)
    B = int(math.floor(a.bpv * ORIG.size / 8))
    base_samples = rd.peer_samples(ORIG)
    xdepth, _ = rd.codec_depth(base_samples["bits"], rd.VIDEO_DEPTHS)
    pf_steps = a.pf_steps or [k * PEAK / 64 for k in (1, 2, 4)]
    nmax = ORIG.size // 4
    work = tempfile.mkdtemp(prefix=f"{os.path.splitext(vname)[0]}_{a.bpv:g}_", dir=tempfile.gettempdir())
    new = not os.path.exists(CSV)
    fcsv = open(CSV, "a", newline="")
    w = csv.DictWriter(fcsv, fieldnames=FIELDS)
    if new:
        w.writeheader()

    def emit(**kw):
        row = dict(volume=vname, bpv=a.bpv, budget=B)
        row.update(kw)
        pb = row.get("points_bytes") or 0
        lb = row.get("layer_bytes") or 0
        row["total_bytes"] = pb + lb + (row.get("side_bytes") or 0)
        row["share_actual"] = round(pb / B, 4)
        for k in ("psnr", "spline_psnr", "seconds"):
            if isinstance(row.get(k), float):
                row[k] = round(row[k], 4)
        assert row["psnr"] is None or row["total_bytes"] <= B, row
        w.writerow(row)
        fcsv.flush()
        print(f"{vname} bpv={a.bpv:g} B={B} {row['order']:7s} {row['layer']:6s} s={row['share_target']}: "
              f"points {pb} + layer {lb} + side {row.get('side_bytes') or 0} = {row['total_bytes']} B, "
              f"PSNR {row['psnr']}  [{row.get('seconds')} s] {row.get('note') or ''}", flush=True)

    if "alone" in a.orders:
        for layer in [l for l in a.layers if l != "dcvj2k"]:  # dcvj2k alone = the product row (or its corners)
            t0 = time.time()
            if layer == "j2kz":
                res, v = run_j2kz(orig64, B - SIDE, work)
                emit(order="alone", layer=layer, share_target=0, points_bytes=0, layer_bytes=res["bytes"],
                     side_bytes=SIDE, psnr=rd.psnr(ORIG, clipv(np.rint(v)), PEAK) if v is not None else None,
                     layer_setting=res["setting"], seconds=time.time() - t0)
                continue
            res, _ = run_layer(layer, base_samples, B, lambda t: clipv(t), work, a.j2k)
            emit(order="alone", layer=layer, share_target=0, points_bytes=0, layer_bytes=res["bytes"], side_bytes=0,
                 psnr=res["psnr"], layer_setting=res["setting"], seconds=time.time() - t0)
        if "dcvj2k" in a.layers:
            t0 = time.time()
            res, dec = dcv_layer(a.volume, 0, B - SIDE, work)
            emit(order="alone", layer="dcvj2k", share_target=0, points_bytes=0, layer_bytes=res["bytes"],
                 side_bytes=SIDE, psnr=rd.psnr(ORIG, dec, PEAK) if dec is not None else None,
                 layer_setting=res["setting"], seconds=time.time() - t0,
                 note="same accounting as pf/tf dcvj2k rows: codestream + 16 B (the product row is the real file)")
        t0 = time.time()
        pw = tempfile.mkdtemp(dir=work)
        pr = fit_points(a.volume, B, pf_steps, pw, nmax)
        emit(order="alone", layer="points", share_target=1, points_bytes=pr["bytes"], layer_bytes=0, side_bytes=0,
             psnr=rd.psnr(ORIG, pr["spline"], PEAK), points_n=pr["n"], points_step=pr["step"],
             seconds=time.time() - t0)
    if "product" in a.orders:
        t0 = time.time()
        out = os.path.join(work, "product.dcv")
        subprocess.run(["nice", "-n", "10", DCV, "compress", a.volume, out, "--bpv", repr(a.bpv), "-f", "-q"],
                       check=True)
        dec = os.path.join(work, "product.nrrd")
        subprocess.run(["nice", "-n", "10", DCV, "decompress", out, dec, "-f", "-q"], check=True)
        inf = subprocess.run([DCV, "info", out], stdout=subprocess.PIPE, text=True).stdout
        lay = re.search(r"residual layer: (\d+) bytes", inf)
        pts = re.search(r"points: (\d+)", inf)
        sz = os.path.getsize(out)
        emit(order="product", layer="dcv", share_target="", points_bytes=sz - (int(lay.group(1)) if lay else 0),
             layer_bytes=int(lay.group(1)) if lay else 0, side_bytes=0, psnr=rd.psnr(ORIG, rd.read_nrrd(dec), PEAK),
             points_n=pts.group(1) if pts else "", seconds=time.time() - t0,
             note="points_bytes = file - layer (container + points)")

    for s in [s for s in a.shares if s > 0]:
        if "pf" in a.orders:
            t0 = time.time()
            pw = tempfile.mkdtemp(dir=work)
            pr = fit_points(a.volume, int(s * B), pf_steps, pw, nmax)
            if pr is None:
                for layer in a.layers:
                    emit(order="pf", layer=layer, share_target=s, psnr=None, note="8 points do not fit s*B")
            else:
                spline = pr["spline"]
                sp = rd.psnr(ORIG, spline, PEAK)
                r = orig64 - spline
                lb = B - pr["bytes"] - SIDE
                for layer in a.layers:
                    t1 = time.time()
                    if layer == "j2kz":
                        res, v = run_j2kz(r, lb, work)
                        emit(order="pf", layer=layer, share_target=s, points_bytes=pr["bytes"],
                             layer_bytes=res["bytes"], side_bytes=SIDE if res["bytes"] is not None else 0,
                             psnr=rd.psnr(ORIG, clipv(np.rint(spline + v)), PEAK) if v is not None else None,
                             points_n=pr["n"], points_step=pr["step"], spline_psnr=sp, layer_setting=res["setting"],
                             seconds=time.time() - t1,
                             note=f"residual RMS {np.sqrt(np.mean(r.astype(float) ** 2)):.3f}")
                        continue
                    if layer == "dcvj2k":
                        off = -int(r.min())
                        rv = r + off
                        src = os.path.join(work, "r.nrrd")
                        write_nrrd(src, rv.astype(np.uint8 if rv.max() <= 255 else np.uint16))
                        res, dl = dcv_layer(src, off, lb, work)
                        if dl is not None:
                            res["psnr"] = rd.psnr(ORIG, clipv(spline + dl), PEAK)
                        note = f"residual + {off} as {'uint8' if rv.max() <= 255 else 'uint16'}"
                        note += f"; residual RMS {np.sqrt(np.mean(r.astype(float) ** 2)):.3f}"
                        emit(order="pf", layer=layer, share_target=s, points_bytes=pr["bytes"],
                             layer_bytes=res["bytes"], side_bytes=SIDE if res["bytes"] is not None else 0,
                             psnr=res["psnr"], points_n=pr["n"], points_step=pr["step"], spline_psnr=sp,
                             layer_setting=res["setting"], seconds=time.time() - t1, note=note)
                        continue
                    if layer == "x265":
                        smp, qstep, mid, floor = residual_samples_x265(r, xdepth)
                        hook = (lambda t, qstep=qstep, mid=mid: clipv(spline + (t.astype(np.int64) - mid) * qstep))
                        note = f"residual {xdepth}-bit, step {qstep}, floor MSE {floor:.3g}"
                    else:
                        smp = residual_samples_j2k(r)
                        hook = (lambda t: clipv(spline + t))
                        note = f"residual {smp['bits']}-bit exact"
                    res, _ = run_layer(layer, smp, lb, hook, work, a.j2k)
                    note += f"; residual RMS {np.sqrt(np.mean(r.astype(float) ** 2)):.3f}"
                    emit(order="pf", layer=layer, share_target=s, points_bytes=pr["bytes"],
                         layer_bytes=res["bytes"], side_bytes=SIDE if res["bytes"] is not None else 0,
                         psnr=res["psnr"], points_n=pr["n"], points_step=pr["step"], spline_psnr=sp,
                         layer_setting=res["setting"], seconds=time.time() - t1 + (t1 - t0 if layer == a.layers[0]
                                                                                   else 0), note=note)
        if "tf" in a.orders:
            for layer in a.layers:
                t0 = time.time()
                lbud = int((1 - s) * B) - SIDE
                if layer == "j2kz":
                    res, v = run_j2kz(orig64, lbud, work)
                    dec = None if v is None else clipv(np.rint(v))
                    if dec is not None:
                        res["psnr"] = rd.psnr(ORIG, dec, PEAK)
                elif layer == "dcvj2k":
                    res, dec = dcv_layer(a.volume, 0, lbud, work)
                    if dec is not None:
                        res["psnr"] = rd.psnr(ORIG, dec, PEAK)
                else:
                    res, dec = run_layer(layer, base_samples, lbud, lambda t: clipv(t), work, a.j2k)
                if dec is None:
                    emit(order="tf", layer=layer, share_target=s, psnr=None, note="layer does not fit")
                    continue
                dec = dec.astype(np.int64)
                e = orig64 - dec
                off = -int(e.min())
                ev = e + off
                dt = np.uint8 if ev.max() <= 255 else np.uint16
                src = os.path.join(work, "e.nrrd")
                write_nrrd(src, ev.astype(dt))
                pw = tempfile.mkdtemp(dir=work)
                ptarget = B - res["bytes"] - SIDE
                pr = fit_points(src, ptarget, a.tf_steps, pw, nmax)
                if pr is None:
                    emit(order="tf", layer=layer, share_target=s, psnr=None, layer_bytes=res["bytes"],
                         note=f"8 points do not fit {ptarget} B")
                    continue
                final = clipv(dec + pr["spline"] - off)
                emit(order="tf", layer=layer, share_target=s, points_bytes=pr["bytes"], layer_bytes=res["bytes"],
                     side_bytes=SIDE, psnr=rd.psnr(ORIG, final, PEAK), points_n=pr["n"], points_step=pr["step"],
                     spline_psnr=res["psnr"], layer_setting=res["setting"], seconds=time.time() - t0,
                     note=f"spline_psnr column = the layer alone at its bytes; e in [{e.min()},{e.max()}] "
                          f"RMS {np.sqrt(np.mean(e.astype(float) ** 2)):.3f}")
    fcsv.close()
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
