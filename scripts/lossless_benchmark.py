#!/usr/bin/python3
"""Lossless and bounded-error comparison of dcv against the lossless and near-lossless codecs of DICOM.

For every volume and every error bound E (in the volume's units: grey levels, Hounsfield units), each codec
codes the volume, is decoded, and its output is checked voxel by voxel: max |original - decoded| <= E.

  dcv      build/tools/dcv/dcv compress IN OUT.dcv --max-error E (a DICOM series: the directory), decompress;
           size = the whole .dcv file
  charls   JPEG-LS by CharLS, NEAR = E (0: lossless), one stream per z slice (benchmark/dcvCharlsPeer.cxx)
  opj      OpenJPEG opj_compress, its default reversible 5/3 (lossless), one .j2k codestream per slice; E = 0
  ojph     OpenJPH ojph_compress -reversible true (HTJ2K, lossless), one .j2c per slice; E = 0
  jxl      JPEG XL cjxl -d 0 -e 9 (lossless; --quick: cjxl's default -e 7), one .jxl per slice; E = 0

The peers code the z slices as separate 2D images, as a DICOM toolkit stores a series (one frame a slice);
their size is the sum of the slices' files. Bits per voxel = 8 * bytes / voxels.

Error bounds (--bounds overrides them for every volume): by sample type, since a bound is in sample units.
  8-bit volumes (the ct-avm*.nrrd CTs too: they are windowed to 8 bits)   E = 0, 1, 2, 4
  deeper integer volumes: CT in Hounsfield units (the dicom-* series) or
  raw int16 CT numbers (headsq-ct.nrrd), and any other deeper integer     E = 0, 1, 2, 5, 10
  float volumes: dcv only, no lossless                                    E = 1, 2, 5, 10
The peers code unsigned integers: uint8 as it is, other integer volumes minus their minimum at the bit depth
that max - min needs (scripts/rd_benchmark.py's peer_samples); a range deeper than 16 bits gets dcv only.
A bound not held by any codec is reported in the table ("bound held": NO) and on stderr, and the exit
status is 1 (2 when a codec failed to run).

CharLS has no command-line tool in Debian (libcharls-dev is the library): the script runs dcvCharlsPeer from
--charls, else build/benchmark/dcvCharlsPeer (built with the project when CharLS is installed), else compiles
benchmark/dcvCharlsPeer.cxx with g++ into the output folder (again whenever the source is newer).

Default volumes: every *.nrrd and every dicom-* series directory in ../shared/data. A series is read as dcv
convert gives it (Hounsfield units); without dcv (peers only) it is read with pydicom (python3-pydicom).

Results: a Markdown table on stdout and in build/lossless/lossless.md (the codecs' versions and settings
first, then bits per voxel per volume and E with dcv's ratios, then every run's bytes, max error and seconds),
a CSV in build/lossless/lossless.csv and a plot in build/lossless/lossless.png (bits per voxel against E, one
subplot per volume). --merge adds the rows of earlier runs' CSV files (this run wins for the same volume, E
and codec), e.g. run the peers once and dcv later.

Tools (Debian): libcharls-dev, libopenjp2-tools, openjph-tools, libjxl-tools, g++ (for dcvCharlsPeer).

Examples:
  scripts/lossless_benchmark.py --volumes head-mr.nrrd neghip.nrrd --codecs charls opj ojph jxl
  scripts/lossless_benchmark.py --codecs charls opj ojph jxl --out build/lossless-peers -j 2
  scripts/lossless_benchmark.py --codecs dcv --merge build/lossless-peers/lossless.csv
  scripts/lossless_benchmark.py --volumes headsq-ct.nrrd --bounds 0 3 --quick
"""

import argparse
import concurrent.futures
import csv
import glob
import os
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rd_benchmark as rd  # noqa: E402  (the volume reading and the peers' samples are shared with it)
import numpy as np  # noqa: E402  (after rd_benchmark, which says how to install it when missing)

REPO = rd.REPO
CODECS = ["dcv", "charls", "opj", "ojph", "jxl"]
LABELS = {"dcv": "dcv", "charls": "CharLS", "opj": "OpenJPEG", "ojph": "OpenJPH", "jxl": "JPEG XL"}
LOSSLESS_ONLY = {"opj", "ojph", "jxl"}
TOOLS = {"opj": ["opj_compress", "opj_decompress"], "ojph": ["ojph_compress", "ojph_expand"], "jxl": ["cjxl", "djxl"]}
APT = {"opj_compress": "libopenjp2-tools", "opj_decompress": "libopenjp2-tools", "ojph_compress": "openjph-tools",
       "ojph_expand": "openjph-tools", "cjxl": "libjxl-tools", "djxl": "libjxl-tools"}
CHARLS_SRC = os.path.join(REPO, "benchmark", "dcvCharlsPeer.cxx")
ROW_KEYS = ["volume", "kind", "voxels", "E", "codec", "bytes", "bpv", "max_err", "held", "enc", "dec", "setting"]


def volume_kind(vname, vol, series):
    """(kind, default bounds) by sample type; see the module docstring."""
    if not np.issubdtype(vol.dtype, np.integer):
        return str(vol.dtype), [1, 2, 5, 10]
    if vol.dtype.itemsize == 1:
        return "8-bit", [0, 1, 2, 4]
    if series:
        return "CT, HU", [0, 1, 2, 5, 10]
    return ("CT, " if "ct" in vname.lower() else "") + str(vol.dtype), [0, 1, 2, 5, 10]


def read_dicom_series(directory):
    """A series as HU, slices sorted along their normal, for runs without dcv (dcv convert is the reference)."""
    import pydicom
    ds = [d for d in (pydicom.dcmread(f) for f in sorted(glob.glob(os.path.join(directory, "*")))) if "PixelData" in d]
    o = np.array(ds[0].ImageOrientationPatient, float)
    normal = np.cross(o[:3], o[3:])
    ds.sort(key=lambda d: float(np.dot(normal, np.array(d.ImagePositionPatient, float))))
    hu = np.stack([d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept) for d in ds])
    return hu.astype(np.int16) if np.all(hu == np.round(hu)) and hu.min() >= -32768 and hu.max() < 32768 else hu


def max_error(vol, rec):
    if rec.shape != vol.shape:
        raise RuntimeError(f"decoded shape {rec.shape} != original {vol.shape}")
    return float(np.max(np.abs(vol.astype(np.float64) - rec.astype(np.float64))))


# ------------------------------------------------------------------------------------------------------ codecs

def codec_dcv(vpath, vol, s, E, work, ctx):
    out, dec = os.path.join(work, "out.dcv"), os.path.join(work, "dec.nrrd")
    t_enc = rd.run([ctx["dcv"], "compress", vpath, out, "--max-error", f"{E:g}", "-f", "-q"])
    t_dec = rd.run([ctx["dcv"], "decompress", out, dec, "-f", "-q"])
    return dict(bytes=os.path.getsize(out), rec=rd.read_nrrd(dec), enc=t_enc, dec=t_dec,
                setting=f"compress --max-error {E:g}; decompress")


def codec_charls(vpath, vol, s, E, work, ctx):
    near = int(E)  # JPEG-LS NEAR is an integer; floor(E) keeps the bound
    cv = rd.coded(s, 8 if s["bits"] <= 8 else 16, 0)
    z, y, x = cv.shape
    # one dcvCharlsPeer a worker, each on a contiguous run of slices (each slice is still its own JPEG-LS image)
    chunks = [c for c in np.array_split(np.arange(z), ctx["jobs"]) if c.size]

    def part(c):
        src, dst = os.path.join(work, f"in{c[0]}.raw"), os.path.join(work, f"dec{c[0]}.raw")
        cv[c[0]:c[-1] + 1].tofile(src)
        p = subprocess.run([ctx["charls"], src, str(x), str(y), str(c.size), str(s["bits"]), str(near), dst],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=rd.TIMEOUT)
        if p.returncode:
            raise RuntimeError(f"dcvCharlsPeer failed ({p.returncode}): {p.stderr[-600:]}")
        out = dict(line.split() for line in p.stdout.splitlines())
        return out, np.fromfile(dst, dtype=cv.dtype).reshape(c.size, y, x)

    with concurrent.futures.ThreadPoolExecutor(ctx["jobs"]) as ex:
        parts = list(ex.map(part, chunks))
    return dict(bytes=sum(int(o["bytes"]) for o, _ in parts),
                rec=rd.restore(s, np.concatenate([r for _, r in parts]), 0),
                enc=sum(float(o["encode_seconds"]) for o, _ in parts),
                dec=sum(float(o["decode_seconds"]) for o, _ in parts),
                setting=f"NEAR={near}, {s['bits']}-bit, default thresholds, one JPEG-LS stream a slice")


def write_pgm(path, img, maxval):
    with open(path, "wb") as f:
        f.write(f"P5\n{img.shape[1]} {img.shape[0]}\n{maxval}\n".encode())
        f.write(img.astype(np.uint8 if maxval < 256 else ">u2").tobytes())  # PGM: 2 bytes big-endian above 255


def per_slice(s, work, ctx, ext, enc, dec, maxval=None):
    """Codes every z slice as its own PGM -> file -> PGM round trip; enc(pgm, file) and dec(file, pgm) give the
    commands. Returns bytes (sum of the files), the decoded volume and the seconds summed over slices."""
    cv = rd.coded(s, 8 if s["bits"] <= 8 else 16, 0)
    maxval = maxval or (1 << s["bits"]) - 1

    def one(k):
        src, out, back = (os.path.join(work, f"s{k}.{e}") for e in ("pgm", ext, "dec.pgm"))
        write_pgm(src, cv[k], maxval)
        t_enc = rd.run(enc(src, out))
        size = os.path.getsize(out)
        t_dec = rd.run(dec(out, back))
        rec = rd.read_pgm(back)
        for f in (src, out, back):
            os.remove(f)
        return size, rec, t_enc, t_dec

    with concurrent.futures.ThreadPoolExecutor(ctx["jobs"]) as ex:
        res = list(ex.map(one, range(cv.shape[0])))
    return dict(bytes=sum(r[0] for r in res), rec=rd.restore(s, np.stack([r[1] for r in res]), 0),
                enc=sum(r[2] for r in res), dec=sum(r[3] for r in res))


def codec_opj(vpath, vol, s, E, work, ctx):
    nres = rd.opj_nres(vol.shape[2], vol.shape[1])  # every resolution level needs a sample (default 6)
    r = per_slice(s, work, ctx, "j2k", lambda i, o: ["opj_compress", "-i", i, "-o", o, "-n", str(nres)],
                  lambda i, o: ["opj_decompress", "-i", i, "-o", o])
    r["setting"] = f"reversible 5/3 (default), -n {nres}, {s['bits']}-bit PGM, .j2k codestream a slice"
    return r


def codec_ojph(vpath, vol, s, E, work, ctx):
    r = per_slice(s, work, ctx, "j2c", lambda i, o: ["ojph_compress", "-i", i, "-o", o, "-reversible", "true"],
                  lambda i, o: ["ojph_expand", "-i", i, "-o", o])
    r["setting"] = f"-reversible true (5 decompositions, 64x64 blocks), {s['bits']}-bit PGM, .j2c a slice"
    return r


def codec_jxl(vpath, vol, s, E, work, ctx):
    effort = "7" if ctx["quick"] else "9"
    # cjxl 0.7 is NOT lossless on a 12-bit PGM (maxval 4095): it came back in steps of 16, errors up to 8.
    # Deeper samples go in as a 16-bit PGM (maxval 65535) with their values unscaled: lossless, as checked
    maxval = 255 if s["bits"] <= 8 else 65535
    r = per_slice(s, work, ctx, "jxl", lambda i, o: ["cjxl", i, o, "-d", "0", "-e", effort, "--quiet"],
                  lambda i, o: ["djxl", i, o, "--quiet"], maxval)
    r["setting"] = (f"-d 0 -e {effort}" + (" (--quick)" if ctx["quick"] else "") + f", PGM maxval {maxval}"
                    + ("" if maxval == 255 else f" ({s['bits']}-bit values)") + ", .jxl a slice")
    return r


CODEC_FUNCS = {"dcv": codec_dcv, "charls": codec_charls, "opj": codec_opj, "ojph": codec_ojph, "jxl": codec_jxl}


# ------------------------------------------------------------------------------------------------------- tools

def charls_tool(path, out):
    """The dcvCharlsPeer to run (see the module docstring), or (None, why)."""
    if path:
        return (path, None) if os.access(path, os.X_OK) else (None, f"--charls {path} is not executable")
    built = os.path.join(REPO, "build", "benchmark", "dcvCharlsPeer")
    if os.access(built, os.X_OK):
        return built, None
    exe = os.path.join(out, "dcvCharlsPeer")
    if os.access(exe, os.X_OK) and os.path.getmtime(exe) >= os.path.getmtime(CHARLS_SRC):
        return exe, None
    if shutil.which("g++") is None:
        return None, "dcvCharlsPeer missing and no g++ to build it"
    pc = subprocess.run(["pkg-config", "--cflags", "--libs", "charls"], capture_output=True, text=True) \
        if shutil.which("pkg-config") else None
    flags = pc.stdout.split() if pc is not None and pc.returncode == 0 else ["-lcharls"]
    p = subprocess.run(["g++", "-O2", "-std=c++17", "-o", exe, CHARLS_SRC] + flags, capture_output=True, text=True)
    if p.returncode:
        return None, f"cannot build dcvCharlsPeer (apt-get install libcharls-dev?): {p.stderr.strip()[-300:]}"
    print(f"lossless_benchmark: built {shown(exe)}", file=sys.stderr)
    return exe, None


def shown(path):
    """A path as the messages show it: relative to the repository when inside it."""
    rel = os.path.relpath(os.path.abspath(path), REPO)
    return os.path.abspath(path) if rel.startswith("..") else rel


def first_line(cmd, match=None):
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None
    lines = [ln.strip() for ln in (p.stdout + p.stderr).splitlines() if ln.strip()]
    lines = [ln for ln in lines if match is None or match in ln]
    return lines[0] if lines else None


def versions(codecs, ctx):
    """One line per codec: its version and the settings the benchmark uses."""
    v = {}
    if "dcv" in codecs:
        v["dcv"] = f"{first_line([ctx['dcv'], '--version']) or ctx['dcv']}: compress --max-error E, decompress"
    if "charls" in codecs:
        lib = first_line([ctx["charls"], "--version"]) if ctx.get("charls") else None
        v["charls"] = (f"{lib or 'CharLS (version unknown)'} (library; benchmark/dcvCharlsPeer.cxx): "
                       "NEAR = E, default JPEG-LS thresholds and reset, no interleave")
    if "opj" in codecs:
        lib = (first_line(["opj_compress", "-h"], "compiled against") or "").split("library")[-1].strip(" .")
        v["opj"] = f"opj_compress (openjp2 {lib or '?'}): default reversible 5/3, -n 6 (fewer on slices < 32 px)"
    if "ojph" in codecs:  # ojph_compress prints no version: the Debian package's
        pkg = first_line(["dpkg-query", "-W", "-f", "${Version}", "openjph-tools"])
        v["ojph"] = f"ojph_compress (openjph-tools {pkg or '?'}): -reversible true, other options default"
    if "jxl" in codecs:
        v["jxl"] = f"{first_line(['cjxl', '--version']) or 'cjxl'}: -d 0 -e {'7' if ctx['quick'] else '9'}, djxl"
    return v


# ------------------------------------------------------------------------------------------------------ output

def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def wide_rows(rows):
    """Per (volume, E): bpv of each codec, dcv's max error, bound held, dcv / best peer, dcv / reference peer
    (JPEG XL at E = 0, CharLS at E > 0)."""
    out = {}
    for r in rows:
        w = out.setdefault((r["volume"], r["E"]), dict(volume=r["volume"], kind=r["kind"], E=r["E"], bpv={},
                                                      err=None, bad=[], failed=[]))
        w["bpv"][r["codec"]] = r["bpv"]
        if r["codec"] == "dcv":
            w["err"] = r["max_err"]
        if r["held"] is False:
            w["bad"].append(f"{r['codec']} {r['max_err']:g}")
        elif r["held"] is None:
            w["failed"].append(r["codec"])
    for w in out.values():
        peers = [b for c, b in w["bpv"].items() if c != "dcv" and b is not None]
        d = w["bpv"].get("dcv")
        ref = w["bpv"].get("jxl" if w["E"] == 0 else "charls")
        w["best"] = d / min(peers) if d is not None and peers and min(peers) > 0 else None
        w["ref"] = d / ref if d is not None and ref else None
        w["held"] = "; ".join(([f"NO: {', '.join(w['bad'])}"] if w["bad"] else []) +
                              ([f"failed: {', '.join(w['failed'])}"] if w["failed"] else [])) or "yes"
    return sorted(out.values(), key=lambda w: (w["volume"], w["E"]))


def markdown(rows, codecs, vers, notes):
    cols = [c for c in CODECS if c in codecs or any(r["codec"] == c for r in rows)]
    head = ["volume", "type", "E"] + [f"{LABELS[c]} bpv" for c in cols] + \
           ["dcv max err", "bound held", "dcv / best peer", "dcv / JPEG XL (E=0), CharLS (E>0)"]
    lines = ["Codecs:", ""] + [f"- {LABELS[c]}: {vers[c]}" for c in cols if c in vers] + [""]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    wide = wide_rows(rows)

    def line(cells):
        lines.append("| " + " | ".join(cells) + " |")

    for w in wide:
        line([w["volume"], w["kind"], f"{w['E']:g}"] + [fmt(w["bpv"].get(c), ".3f") for c in cols] +
             [fmt(w["err"], "g"), w["held"], fmt(w["best"], ".3f"), fmt(w["ref"], ".3f")])
    # the means over volumes, per E (a column's mean is over the volumes that have it: (n) when fewer)
    for E in sorted({w["E"] for w in wide}):
        ws = [w for w in wide if w["E"] == E]

        def mean(vals):
            vals = [v for v in vals if v is not None]
            return "-" if not vals else f"{np.mean(vals):.3f}" + ("" if len(vals) == len(ws) else f" ({len(vals)})")
        label = f"**mean of {len(ws)} volume{'s' if len(ws) > 1 else ''}**"
        line([label, "", f"{E:g}"] + [mean(w["bpv"].get(c) for w in ws) for c in cols] +
             ["", "NO" if any(w["bad"] for w in ws) else ("yes" if all(w["held"] == "yes" for w in ws) else "-"),
              mean(w["best"] for w in ws), mean(w["ref"] for w in ws)])

    lines += ["", "Every run:", "", "| volume | E | codec | bytes | bpv | max err | bound held | encode s | decode s | "
              "setting |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        held = "-" if r["held"] is None else ("yes" if r["held"] else "NO")
        line([r["volume"], f"{r['E']:g}", r["codec"], fmt(r["bytes"], "d"), fmt(r["bpv"], ".4f"),
              fmt(r["max_err"], "g"), held, fmt(r["enc"], ".2f"), fmt(r["dec"], ".2f"), r["setting"].replace("|", "/")])
    text = "\n".join(lines) + "\n"
    if notes:
        text += "\nNotes:\n\n" + "\n".join(f"- {n}" for n in notes) + "\n"
    return text


def read_rows(path):
    """The rows of an earlier run's lossless.csv, typed as this run's rows (empty cells -> None)."""
    types = dict(voxels=int, E=float, bytes=int, bpv=float, max_err=float, enc=float, dec=float,
                 held=lambda v: v == "True")
    with open(path, newline="") as f:
        return [{k: r[k] if k in ("volume", "kind", "codec", "setting") else (types[k](r[k]) if r[k] else None)
                 for k in ROW_KEYS} for r in csv.DictReader(f)]


def plot(rows, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("lossless_benchmark: python3-matplotlib missing: no plot", file=sys.stderr)
        return None
    vols = sorted({r["volume"] for r in rows})
    ncol = min(3, len(vols))
    nrow = -(-len(vols) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.6 * nrow), squeeze=False)
    for ax, vol in zip(axes.flat, vols):
        for i, codec in enumerate(CODECS):  # one colour a codec in every subplot
            pts = sorted((r["E"], r["bpv"]) for r in rows if r["volume"] == vol and r["codec"] == codec
                         and r["bpv"] is not None)
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=f"C{i}", label=LABELS[codec])
        es = sorted({r["E"] for r in rows if r["volume"] == vol})
        ax.set_xticks(es)
        ax.set_xticklabels([f"{e:g}" for e in es])
        kind = next(r["kind"] for r in rows if r["volume"] == vol)
        ax.set_title(f"{vol} ({kind})", fontsize=10)
        ax.set_xlabel("max error E")
        ax.set_ylabel("bits per voxel (whole files)")
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    for ax in list(axes.flat)[len(vols):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# -------------------------------------------------------------------------------------------------------- main

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=rd.DEFAULT_DATA, help="folder of the volumes (default ../shared/data)")
    ap.add_argument("--volumes", nargs="+", help="names in --data (default: every *.nrrd and dicom-* series)")
    ap.add_argument("--bounds", nargs="+", type=float, help="the bounds E for every volume (default: by type)")
    ap.add_argument("--codecs", nargs="+", choices=CODECS, default=CODECS)
    ap.add_argument("--dcv", default=os.path.join(REPO, "build", "tools", "dcv", "dcv"))
    ap.add_argument("--charls", help="dcvCharlsPeer (default: build/benchmark/dcvCharlsPeer, else built into --out)")
    ap.add_argument("--out", default=os.path.join(REPO, "build", "lossless"), help="output folder (build/lossless)")
    ap.add_argument("-j", "--jobs", type=int, default=2, help="worker processes for the peers' slices (default 2)")
    ap.add_argument("--quick", action="store_true", help="JPEG XL at cjxl's default -e 7 instead of the slow -e 9")
    ap.add_argument("--merge", nargs="+", metavar="CSV", default=[],
                    help="lossless.csv files of earlier runs, combined with this run's rows (this run wins)")
    ap.add_argument("--keep", action="store_true", help="keep the work folders")
    args = ap.parse_args()

    merged = [r for fn in args.merge for r in read_rows(fn)]  # read first: a bad path fails before the long run
    os.makedirs(args.out, exist_ok=True)
    ctx = dict(dcv=args.dcv, jobs=max(1, args.jobs), quick=args.quick)
    notes, missing = [], []
    dcv_ok = os.path.isfile(args.dcv) and os.access(args.dcv, os.X_OK)
    if "dcv" in args.codecs and not dcv_ok:
        missing.append(f"dcv ({args.dcv}: build the project first)")
    if "charls" in args.codecs:
        ctx["charls"], why = charls_tool(args.charls, args.out)
        if why:
            missing.append(why)
    for codec in args.codecs:
        missing += [f"{t} (apt-get install {APT[t]})" for t in TOOLS.get(codec, []) if shutil.which(t) is None]
    usable = [c for c in args.codecs if (c != "dcv" or dcv_ok) and (c != "charls" or ctx.get("charls"))
              and all(shutil.which(t) for t in TOOLS.get(c, []))]
    if missing:
        print("lossless_benchmark: MISSING TOOLS: " + "; ".join(missing), file=sys.stderr)
        notes.append("missing tools, their codecs are skipped: " + "; ".join(missing))

    rows, failed = [], []
    for vname in args.volumes or rd.list_volumes(args.data):
        vpath = os.path.join(args.data, vname)
        if os.path.isdir(vpath) and not dcv_ok:
            vol = read_dicom_series(vpath)
            notes.append(f"{vname}: read with pydicom (no dcv to convert it); dcv convert may order the slices "
                         "the other way, which leaves the per-slice peers' sizes unchanged")
        else:
            vol = rd.load_volume(vpath, args.dcv, args.out)
        kind, bounds = volume_kind(vname, vol, os.path.isdir(vpath))
        s = rd.peer_samples(vol)
        if s is not None and s["bits"] > 16:
            notes.append(f"{vname}: its range needs {s['bits']} bits, the peers take at most 16: dcv only")
            s = None
        if s is not None and s["offset"]:
            notes.append(f"{vname} ({vol.dtype}, {vol.min()}..{vol.max()}): the peers code value - min "
                         f"(min = {s['offset']}) as {s['bits']}-bit unsigned samples; the minimum is added back "
                         "before the error check (a few bytes of side information, not counted)")
        floating = not np.issubdtype(vol.dtype, np.integer)
        for E in sorted(args.bounds or bounds):
            if floating and E == 0:
                continue  # float volumes: bounded error only
            for codec in usable:
                if codec != "dcv" and (s is None or (E > 0 and codec in LOSSLESS_ONLY)):
                    continue
                work = tempfile.mkdtemp(prefix=f"{os.path.splitext(vname)[0]}_{E:g}_{codec}_", dir=args.out)
                t0 = time.perf_counter()
                try:
                    res = CODEC_FUNCS[codec](vpath, vol, s, E, work, ctx)
                    err = max_error(vol, res.pop("rec"))
                    held = err <= E
                except Exception as e:  # report and carry on
                    res = dict(bytes=None, enc=None, dec=None, setting=f"ERROR: {e}".replace("\n", " "))
                    err = held = None
                    failed.append(f"{vname} E={E:g} {codec}")
                if not args.keep:
                    shutil.rmtree(work, ignore_errors=True)
                row = dict(volume=vname, kind=kind, voxels=vol.size, E=E, codec=codec, bytes=res["bytes"],
                           bpv=None if res["bytes"] is None else 8.0 * res["bytes"] / vol.size, max_err=err,
                           held=held, enc=res["enc"], dec=res["dec"], setting=res["setting"])
                rows.append(row)
                print(f"[{time.perf_counter() - t0:7.1f} s] {vname} E={E:g} {codec}: bytes={row['bytes']} "
                      f"bpv={fmt(row['bpv'], '.4f')} max err={fmt(err, 'g')}"
                      + (" BOUND VIOLATED" if held is False else "") + f" ({row['setting']})",
                      file=sys.stderr, flush=True)

    if merged:
        table = {(r["volume"], r["E"], r["codec"]): r for r in merged + rows}  # later wins: this run last
        notes.append(f"{len(table) - len(rows)} rows merged from {', '.join(args.merge)}; their times are theirs")
        rows = list(table.values())
        if "charls" not in usable and any(r["codec"] == "charls" for r in rows):
            ctx["charls"] = charls_tool(args.charls, args.out)[0]  # for its version line
        notes.append("the codecs' versions are those installed now, also for the merged rows")
    order = {c: i for i, c in enumerate(CODECS)}
    rows.sort(key=lambda r: (r["volume"], r["E"], order[r["codec"]]))

    notes.append("bpv = 8 * bytes / voxels; dcv: the whole .dcv file (a DICOM series' attributes included); the "
                 "peers: the sum of their per-slice files (JPEG-LS / J2K codestreams, .jxl files), no DICOM "
                 "wrapper. Max err = max |original - decoded| over all voxels, in the volume's units.")
    notes.append(f"seconds: dcv: wall-clock of its compress / decompress CLI runs (its own threading); CharLS: "
                 f"the library's encode / decode time summed over slices; the other peers: the wall-clock of their "
                 f"per-slice CLI runs summed over slices (process start and PGM files included), run "
                 f"{ctx['jobs']} at a time (-j).")
    notes.append("dcv / best peer: dcv's bpv over the smallest peer bpv at that E (at E > 0 only CharLS codes "
                 "near-lossless); dcv / JPEG XL (E=0), CharLS (E>0): over that peer's bpv. Mean rows: arithmetic "
                 "means over the volumes at that E.")
    text = markdown(rows, usable, versions({r["codec"] for r in rows} | set(usable), ctx), notes)
    print(text)
    cmd = " ".join([os.path.relpath(sys.argv[0], REPO)] + sys.argv[1:])
    with open(os.path.join(args.out, "lossless.md"), "w") as f:
        f.write(f"# Lossless and bounded-error comparison\n\nCommand: `{cmd}`\n\n" + text)
    with open(os.path.join(args.out, "lossless.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=ROW_KEYS)
        w.writeheader()
        w.writerows(rows)
    png = plot(rows, os.path.join(args.out, "lossless.png"))
    for fn in ("lossless.md", "lossless.csv") + ((os.path.basename(png),) if png else ()):
        print(f"wrote {shown(os.path.join(args.out, fn))}", file=sys.stderr)

    bad = [f"{r['volume']} E={r['E']:g} {r['codec']}: max err {r['max_err']:g}" for r in rows if r["held"] is False]
    if bad:
        print("lossless_benchmark: ERROR BOUND VIOLATED: " + "; ".join(bad), file=sys.stderr)
        return 1
    if failed:
        print("lossless_benchmark: FAILED RUNS: " + "; ".join(failed), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
