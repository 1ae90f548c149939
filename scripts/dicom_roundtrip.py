#!/usr/bin/python3
"""Compares a DICOM series returned by `dcv decompress --dicom` with the original: slice positions and
the PSNR in Hounsfield units (peak: max - min of the original), as the README reports them.

    /usr/bin/python3 scripts/dicom_roundtrip.py ORIGINAL_DIR RETURNED_DIR

Needs numpy and pydicom (Debian: python3-numpy, python3-pydicom, for /usr/bin/python3)."""
import glob
import sys

try:
    import numpy as np
    import pydicom
except ImportError as e:
    sys.exit(f"dicom_roundtrip: {e.name} is missing (apt-get install python3-{e.name}); run with /usr/bin/python3")


def read_series(directory):
    """The slices sorted along the normal of their orientation: HU, positions, datasets."""
    datasets = [pydicom.dcmread(f) for f in sorted(glob.glob(directory + "/*"))]
    datasets = [d for d in datasets if "PixelData" in d]
    o = np.array(datasets[0].ImageOrientationPatient, float)
    normal = np.cross(o[:3], o[3:])
    datasets.sort(key=lambda d: float(np.dot(normal, np.array(d.ImagePositionPatient, float))))
    hu = np.stack([d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept) for d in datasets])
    positions = np.array([[float(v) for v in d.ImagePositionPatient] for d in datasets])
    return hu, positions, datasets


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    a, pa, _ = read_series(sys.argv[1])
    b, pb, db = read_series(sys.argv[2])
    if a.shape != b.shape:
        sys.exit("different sizes: %s and %s" % (a.shape, b.shape))
    peak = a.max() - a.min()
    mse = np.mean((a - b) ** 2)
    print("original: %g..%g HU, returned: %g..%g HU" % (a.min(), a.max(), b.min(), b.max()))
    print("returned: bits stored %s, pixel representation %s, rescale intercept %s, slope %s"
          % (db[0].BitsStored, db[0].PixelRepresentation, db[0].RescaleIntercept, db[0].RescaleSlope))
    print("largest slice position difference: %.3g mm" % np.abs(pa - pb).max())
    print("PSNR: %.6f dB (peak %g)" % (10 * np.log10(peak * peak / mse), peak))


if __name__ == "__main__":
    main()
