#!/usr/bin/python3
# Copyright NumFOCUS; licensed under the Apache License, Version 2.0 (LICENSE).
"""The 3D Slicer extension's screenshot: runs the DCVApproximate module on a volume as Slicer would
(parameters by flag, volumes by position, --returnparameterfile) and renders the middle axial and coronal
slices of the original, the approximation and the absolute error side by side.

    /usr/bin/python3 scripts/slicer_screenshot.py build/slicer/DCVApproximate ../shared/data/avg152t1.nrrd \
        slicer/Resources/Screenshot-DCVApproximate.png [--bpv 0.0625]
"""
import argparse
import gzip
import os
import subprocess
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

TYPES = {"uchar": np.uint8, "unsigned char": np.uint8, "uint8": np.uint8, "char": np.int8, "signed char": np.int8,
         "short": np.int16, "int16": np.int16, "ushort": np.uint16, "unsigned short": np.uint16, "uint16": np.uint16,
         "int": np.int32, "int32": np.int32, "uint": np.uint32, "unsigned int": np.uint32, "uint32": np.uint32,
         "float": np.float32, "double": np.float64}


def read_nrrd(path):
    """A 3D NRRD with its data attached (raw or gzip), as ITK writes it: array indexed [z, y, x]."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"\n\n")
    fields = {}
    for line in data[:end].decode("latin-1").splitlines()[1:]:
        if line.startswith("#") or ": " not in line:
            continue
        key, value = line.split(": ", 1)
        fields[key.strip()] = value.strip()
    payload = data[end + 2:]
    if fields.get("encoding") in ("gzip", "gz"):
        payload = gzip.decompress(payload)
    dtype = np.dtype(TYPES[fields["type"]])
    if fields.get("endian", "little") == "big":
        dtype = dtype.newbyteorder(">")
    sizes = [int(s) for s in fields["sizes"].split()]
    return np.frombuffer(payload, dtype=dtype).reshape(sizes[::-1]).astype(np.float64)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("module")
    parser.add_argument("input")
    parser.add_argument("output")
    parser.add_argument("--bpv", default="0.0625")
    a = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        approximation = os.path.join(work, "approximation.nrrd")
        error = os.path.join(work, "error.nrrd")
        returned = os.path.join(work, "returned.txt")
        subprocess.run([a.module, "--bpv", a.bpv, "--returnparameterfile", returned, a.input, approximation, error],
                       check=True, stdout=subprocess.DEVNULL)
        values = dict(line.split(" = ", 1) for line in open(returned).read().splitlines())
        volumes = [read_nrrd(a.input), read_nrrd(approximation), read_nrrd(error)]
    psnr = float(values["outputPSNR"])
    ratio = 8.0 / float(values["outputBitsPerVoxel"])
    titles = ["original", f"DCV Approximate, {a.bpv} bpv\n{int(values['outputBytes'])} bytes, PSNR {psnr:.2f} dB",
              "absolute error"]
    peak = volumes[0].max()
    figure, axes = plt.subplots(2, 3, figsize=(7.2, 5.0), dpi=100, facecolor="black",
                                gridspec_kw={"height_ratios": [volumes[0].shape[1], volumes[0].shape[0]]})
    for column, (volume, title) in enumerate(zip(volumes, titles)):
        error_view = column == 2
        options = dict(cmap="inferno", vmin=0, vmax=peak / 4) if error_view else dict(cmap="gray", vmin=0, vmax=peak)
        axial = volume[volume.shape[0] // 2]
        coronal = volume[:, volume.shape[1] // 2 + 8, :]
        axes[0, column].imshow(axial[::-1], **options)
        axes[1, column].imshow(coronal[::-1], **options)
        axes[0, column].set_title(title, color="white", fontsize=9)
        for row in (0, 1):
            axes[row, column].set_axis_off()
    figure.suptitle(f"{os.path.basename(a.input)}: about {ratio:.0f}:1 for 8-bit data", color="white", fontsize=10)
    figure.tight_layout()
    figure.savefig(a.output, dpi=100, facecolor="black")


if __name__ == "__main__":
    main()
