#!/usr/bin/python3
# Copyright NumFOCUS; licensed under the Apache License, Version 2.0 (LICENSE).
"""Draws the 3D Slicer extension's icon (128x128 PNG): a slice of a head phantom as the method sees it,
flat-shaded over a Delaunay triangulation of a few significant points, more of them where the image changes.

    /usr/bin/python3 scripts/slicer_icon.py slicer/Resources/DelaunayCompression.png
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.tri as mtri  # noqa: E402
import numpy as np  # noqa: E402


def phantom(x, y):
    """A 2D head: skull ring, brain, two ventricles, a bright spot (values 0..1)."""
    v = np.zeros_like(x)
    v += 1.0 * ((x / 0.69) ** 2 + (y / 0.92) ** 2 <= 1)
    v -= 0.8 * ((x / 0.6624) ** 2 + ((y + 0.0184) / 0.874) ** 2 <= 1)
    v -= 0.2 * (((x - 0.22) / 0.11) ** 2 + (y / 0.31) ** 2 <= 1)
    v -= 0.2 * (((x + 0.22) / 0.16) ** 2 + (y / 0.41) ** 2 <= 1)
    v += 0.3 * ((x / 0.21) ** 2 + ((y - 0.35) / 0.25) ** 2 <= 1)
    v += 0.25 * (((x + 0.08) / 0.046) ** 2 + ((y + 0.605) / 0.023) ** 2 <= 1)
    return np.clip(v, 0, 1)


def main(path):
    rng = np.random.default_rng(7)
    # Candidates; keep those near edges of the phantom (a crude significance), plus a sparse grid.
    cx, cy = rng.uniform(-1, 1, (2, 6000))
    h = 0.04
    edge = np.abs(phantom(cx + h, cy) - phantom(cx - h, cy)) + np.abs(phantom(cx, cy + h) - phantom(cx, cy - h))
    keep = edge > 0.05
    px = np.concatenate([cx[keep][:170], np.repeat(np.linspace(-1, 1, 7), 7)])
    py = np.concatenate([cy[keep][:170], np.tile(np.linspace(-1, 1, 7), 7)])
    triangulation = mtri.Triangulation(px, py)
    centroids = np.stack([px[triangulation.triangles].mean(1), py[triangulation.triangles].mean(1)], 1)
    values = phantom(centroids[:, 0], centroids[:, 1])

    figure = plt.figure(figsize=(1.28, 1.28), dpi=100)
    axes = figure.add_axes([0, 0, 1, 1])
    axes.set_axis_off()
    axes.add_patch(plt.Rectangle((-1, -1), 2, 2, color="#16324f", zorder=0))
    axes.tripcolor(triangulation, facecolors=values, cmap="bone", vmin=-0.05, vmax=1.05, edgecolors="#5d9bd0",
                   linewidth=0.3, zorder=1)
    axes.text(0.93, -0.93, "DCV", color="#ffcf4a", fontsize=15, fontweight="bold", ha="right", va="bottom",
              family="DejaVu Sans", zorder=2)
    axes.set_xlim(-1, 1)
    axes.set_ylim(-1, 1)
    figure.savefig(path, dpi=100)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "slicer/Resources/DelaunayCompression.png")
