#!/usr/bin/python3
"""Why does points-first lose? For one volume, bpv and points share s:

  - points-only .dcv at ~ s*B (partner.fit_points), spline, residual r = original - spline
  - energy: mean square of (original - its mean) vs mean square of r
  - 8x8 DCT of every slice (the transform HEVC uses most): number of coefficients above T (T = 2, 4, 8, 16 on the
    orthonormal DCT) for the original and for r, and their energy outside the DC coefficient
  - creases: the spline is C0 (linear in each tetrahedron, its gradient jumps on the faces); the 3D Laplacian of the
    spline is zero inside the tetrahedra and non-zero on the faces. Reported: ||lap spline||^2 / ||lap r||^2
  - x265 RD on the original and on r (8-bit, same quantization as partner.py) over a CRF sweep: the final PSNR of
    each; the bytes x265 needs on r (plus the points) vs on the original at equal PSNR (log-linear interpolation)
  - PNGs: axial and coronal slices of the original, spline, residual, |lap spline|, points-first x265 final and
    x265 alone at the same budget
Appends to layer-split-why.csv. Usage: why.py VOLUME --bpv 0.0625 --share 0.35
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import partner as P  # noqa: E402  (hooks rd_benchmark.psnr only while partner's HOOK is set)

rd = P.rd


def dct_mat(n=8):
    k = np.arange(n)
    m = np.cos(np.pi * (2 * k[None, :] + 1) * k[:, None] / (2 * n)) * math.sqrt(2.0 / n)
    m[0] /= math.sqrt(2)
    return m


def block_dct(v):
    z, y, x = v.shape
    Y, X = y // 8 * 8, x // 8 * 8
    b = v[:, :Y, :X].astype(np.float64).reshape(z, Y // 8, 8, X // 8, 8)
    m = dct_mat()
    return np.einsum("ij,zajbk,lk->zaibl", m, b, m)  # (z, by, 8, bx, 8)


def lap3(v):
    v = v.astype(np.float64)
    c = v[1:-1, 1:-1, 1:-1]
    return (v[2:, 1:-1, 1:-1] + v[:-2, 1:-1, 1:-1] + v[1:-1, 2:, 1:-1] + v[1:-1, :-2, 1:-1] + v[1:-1, 1:-1, 2:]
            + v[1:-1, 1:-1, :-2] - 6 * c)


def x265_sweep(codes, crfs, work, depth=8):
    z, y, x = codes.shape
    pv = rd.pad_xy(codes.astype(np.uint8), 8)
    _, Y, X = pv.shape
    yuv = os.path.join(work, "in.yuv")
    pv.tofile(yuv)
    out = []
    ctu = [c for c in (64, 32, 16) if c <= min(X, Y)][0]
    for crf in crfs:
        hevc = os.path.join(work, "o.hevc")
        rec = os.path.join(work, "r.yuv")
        subprocess.run(["nice", "-n", "10", "x265", "--input", yuv, "--input-res", f"{X}x{Y}", "--input-csp", "i400",
                        "--input-depth", "8", "--output-depth", "8", "--fps", "25", "--preset", "slower", "--tune",
                        "psnr", "--no-info", "--ctu", str(ctu), "--crf", str(crf), "-o", hevc, "--recon", rec],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        d = np.fromfile(rec, dtype=np.uint8).reshape(z, Y, X)[:, :y, :x]
        out.append((crf, os.path.getsize(hevc), d.astype(np.int64)))
    return out


def bytes_at(curve, p):
    """log-linear interpolation of bytes at PSNR p on [(bytes, psnr)] (None outside the range)"""
    c = sorted(curve, key=lambda t: t[1])
    for (b0, p0), (b1, p1) in zip(c, c[1:]):
        if p0 <= p <= p1 and p1 > p0:
            return math.exp(math.log(b0) + (p - p0) / (p1 - p0) * (math.log(b1) - math.log(b0)))
    return None


def save_png(path, panels, titles):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(2, len(panels[0]), figsize=(2.6 * len(panels[0]), 5.6))
    for r, row in enumerate(panels):
        for c, (img, vmin, vmax) in enumerate(row):
            axs[r, c].imshow(img, cmap="gray", vmin=vmin, vmax=vmax, origin="lower" if r == 1 else "upper",
                             interpolation="nearest", aspect="auto")
            axs[r, c].set_xticks([])
            axs[r, c].set_yticks([])
            if r == 0:
                axs[r, c].set_title(titles[c], fontsize=8)
    axs[0, 0].set_ylabel("axial")
    axs[1, 0].set_ylabel("coronal")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("volume")
    ap.add_argument("--bpv", type=float, required=True)
    ap.add_argument("--share", type=float, default=0.35)
    ap.add_argument("--crfs", type=int, nargs="+", default=[20, 24, 28, 32, 36, 40, 44, 48, 51])
    a = ap.parse_args()
    vname = os.path.basename(a.volume)
    orig = rd.read_nrrd(a.volume)
    assert orig.dtype == np.uint8, "8-bit volumes only"
    P.ORIG = orig
    peak = 255.0
    o = orig.astype(np.int64)
    B = int(a.bpv * orig.size / 8)
    work = tempfile.mkdtemp()
    pr = P.fit_points(a.volume, int(a.share * B), [k * peak / 64 for k in (1, 2, 4)], work, orig.size // 4)
    spline = pr["spline"]
    r = o - spline
    P.LOHI = (0, 255)
    smp, qstep, mid, floor = P.residual_samples_x265(r, 8)
    row = dict(volume=vname, bpv=a.bpv, budget=B, share=a.share, points_bytes=pr["bytes"], points_n=pr["n"],
               points_step=pr["step"], spline_psnr=round(rd.psnr(orig, spline, peak), 3),
               ms_orig_minus_mean=round(float(np.var(o)), 2), ms_residual=round(float(np.mean(r ** 2.0)), 2),
               residual_qstep=qstep)
    # DCT significance
    co, cr = block_dct(o), block_dct(r)
    for T in (2, 4, 8, 16):
        row[f"sig{T}_orig"] = int(np.sum(np.abs(co) > T))
        row[f"sig{T}_resid"] = int(np.sum(np.abs(cr) > T))
    ac = np.ones((8, 8), bool)
    ac[0, 0] = False
    row["ac_energy_orig"] = round(float(np.sum(co[:, :, ac[:, 0].nonzero()[0][:0]] ** 2)) if False else
                                  float(np.sum((co ** 2)) - np.sum(co[:, :, 0, :, 0] ** 2)), 0)
    row["ac_energy_resid"] = round(float(np.sum(cr ** 2) - np.sum(cr[:, :, 0, :, 0] ** 2)), 0)
    # high-frequency AC energy: coefficients with u + v >= 6 (the upper half of the 8x8 block)
    uv = np.add.outer(np.arange(8), np.arange(8)) >= 6
    row["hf_energy_orig"] = round(float(np.sum((co ** 2).transpose(0, 1, 3, 2, 4)[..., uv])), 0)
    row["hf_energy_resid"] = round(float(np.sum((cr ** 2).transpose(0, 1, 3, 2, 4)[..., uv])), 0)
    # creases
    ls, lr, lo = lap3(spline), lap3(r), lap3(o)
    row["lap_energy_spline"] = round(float(np.sum(ls ** 2)), 0)
    row["lap_energy_resid"] = round(float(np.sum(lr ** 2)), 0)
    row["lap_energy_orig"] = round(float(np.sum(lo ** 2)), 0)
    row["frac_spline_in_lap_resid"] = round(float(np.sum(ls ** 2) / np.sum(lr ** 2)), 4)
    row["frac_lap_nonzero_spline"] = round(float(np.mean(np.abs(ls) > 4)), 4)
    # x265 sweeps
    so = x265_sweep(orig, a.crfs, work)
    sr = x265_sweep(smp["codes"], a.crfs, work)
    curve_o = [(b, rd.psnr(orig, d, peak)) for _, b, d in so]
    finals = [np.clip(spline + (d - mid) * qstep, 0, 255) for _, _, d in sr]
    curve_r = [(b + pr["bytes"] + P.SIDE, rd.psnr(orig, f, peak)) for (_, b, _), f in zip(sr, finals)]
    curve_r_layer = [(b, p) for (_, b, _), (_, p) in zip(sr, curve_r)]
    print("crf, bytes orig, PSNR orig, bytes resid layer, total pf, PSNR pf")
    for (c, bo, _), (_, po), (bl, _), (bt, pp) in zip(so, curve_o, curve_r_layer, curve_r):
        print(f"{c:3d} {bo:8d} {po:7.3f} {bl:8d} {bt:8d} {pp:7.3f}")
    ratios = []
    for p in np.linspace(max(min(x[1] for x in curve_o), min(x[1] for x in curve_r)),
                         min(max(x[1] for x in curve_o), max(x[1] for x in curve_r)), 5):
        bo, bl = bytes_at(curve_o, p), bytes_at(curve_r_layer, p)
        if bo and bl:
            ratios.append(f"{p:.2f}dB: orig {bo:.0f} B, resid layer {bl:.0f} B (+points {pr['bytes'] + P.SIDE})")
    row["equal_psnr"] = "; ".join(ratios)
    row["crf_curve_orig"] = " ".join(f"{b}:{p:.2f}" for b, p in curve_o)
    row["crf_curve_pf_total"] = " ".join(f"{b}:{p:.2f}" for b, p in curve_r)
    for k, v in row.items():
        print(f"{k}: {v}")
    fn = "layer-split-why.csv"
    new = not os.path.exists(fn)
    with open(fn, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(row))
        if new:
            w.writeheader()
        w.writerow(row)
    # images at the budget: the PF final and x265 alone that fit B
    fit_r = [i for i, (b, _) in enumerate(curve_r) if b <= B]
    fit_o = [i for i, (b, _) in enumerate(curve_o) if b <= B]
    fpf = finals[fit_r[0]] if fit_r else finals[-1]
    fx = so[fit_o[0]][2] if fit_o else so[-1][2]
    ppf = curve_r[fit_r[0] if fit_r else -1]
    px = curve_o[fit_o[0] if fit_o else -1]
    z, y, x = orig.shape
    lsf = np.zeros(orig.shape)
    lsf[1:-1, 1:-1, 1:-1] = np.abs(ls)
    vols = [(o, 0, 255), (spline, 0, 255), (r, -40, 40), (lsf, 0, 16), (fpf, 0, 255), (fx, 0, 255),
            (o - fpf, -40, 40)]
    titles = ["original", f"spline {pr['n']} pts ({pr['bytes']} B)", "residual (+-40)", "|Laplacian spline| (0..16)",
              f"pf x265 {ppf[0]} B {ppf[1]:.2f} dB", f"x265 alone {px[0]} B {px[1]:.2f} dB", "pf error (+-40)"]
    panels = [[(v[z // 2], lo_, hi_) for v, lo_, hi_ in vols], [(v[:, y // 2, :], lo_, hi_) for v, lo_, hi_ in vols]]
    png = os.path.join(".", f"layer-split-why_{os.path.splitext(vname)[0]}_{a.bpv:g}_{a.share:g}.png")
    save_png(png, panels, titles)
    print("png:", png)


if __name__ == "__main__":
    main()
