#!/usr/bin/python3
"""Writes content/clouds/storm-cell.vdb, the cloud of content/scenes/vdb-cloud.json, with
OpenVDB's Python bindings (Debian python3-openvdb), the way a user's tool would hand Fulgur a
cloud: one float grid "density" (a fog volume, values in [0, 1]), y up, metres.

The procedure (deterministic: numpy's generator seeded with SEED):
  1. A storm cell as a union of ellipsoids: a flat base skirt, a convective tower leaning
     downwind (+x), a few turrets bulging from its flanks, a flat anvil spreading downwind at
     the top and an overshooting dome above it.
  2. Each ellipsoid's normalized radius r (1 on its surface) is perturbed by fractal noise:
     a sum over four octaves of 12 plane waves with random directions and phases (amplitude
     halving and frequency doubling per octave), so the surfaces get cauliflower lumps.
  3. Density = clip(GAIN * (1 - r_min), 0, 1) with r_min the smallest perturbed radius over
     the ellipsoids: a soft edge, a dense core; nothing below the cloud base.
  4. Voxels above 1e-3 are written (sparse), 16-bit floats on disk (the file stays small).

Usage: scripts/make_vdb_cloud.py [OUT.vdb]   (default: content/clouds/storm-cell.vdb)
"""
import os
import sys

import numpy as np
import pyopenvdb as vdb

SEED = 3
VOXEL = 125.0                      # metres
LOWER = (-6000.0, 1000.0, -6000.0)  # x, y (up), z of the box's lower corner, metres
DIMS = (96, 64, 96)                # voxels along x, y (up), z: 12 x 8 x 12 km
BASE = 1500.0                      # cloud base height, metres
GAIN = 1.8

# (centre x, y, z), (radius x, y, z), metres; y up, the wind along +x.
ELLIPSOIDS = [
    ((0.0, 2200.0, 0.0), (3400.0, 800.0, 3200.0)),     # base skirt
    ((0.0, 4000.0, 0.0), (2300.0, 2500.0, 2300.0)),    # tower, lower half
    ((400.0, 6000.0, 0.0), (2000.0, 2100.0, 2000.0)),  # tower, upper half (sheared downwind)
    ((1500.0, 7900.0, 0.0), (4300.0, 700.0, 3800.0)),  # anvil
    ((500.0, 8400.0, 0.0), (1600.0, 650.0, 1600.0)),   # overshooting top
]


def fractal_noise(rng, x, y, z):
    n = np.zeros_like(x)
    amplitude, wavelength = 1.0, 2000.0
    for _ in range(4):
        for _ in range(12):
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            phase = rng.uniform(0.0, 2.0 * np.pi)
            n += amplitude * np.sin(2.0 * np.pi * (d[0] * x + d[1] * y + d[2] * z) / wavelength + phase)
        amplitude *= 0.5
        wavelength *= 0.5
    return n / np.sqrt(12.0 * (1.0 + 0.25 + 0.0625 + 0.015625))  # about unit variance


def main(out):
    rng = np.random.default_rng(SEED)
    axes = [LOWER[a] + (np.arange(DIMS[a]) + 0.5) * VOXEL for a in range(3)]
    x, y, z = np.meshgrid(*axes, indexing="ij")  # array[i, j, k] is voxel (i, j, k): x, y, z

    ellipsoids = list(ELLIPSOIDS)
    for _ in range(6):  # turrets on the tower's flanks
        angle = rng.uniform(0.0, 2.0 * np.pi)
        height = rng.uniform(3500.0, 6500.0)
        radius = rng.uniform(800.0, 1300.0)
        ellipsoids.append(((1900.0 * np.cos(angle), height, 1900.0 * np.sin(angle)), (radius, radius, radius)))

    noise = fractal_noise(rng, x, y, z)
    r_min = np.full(x.shape, np.inf)
    for (cx, cy, cz), (rx, ry, rz) in ellipsoids:
        r = np.sqrt(((x - cx) / rx) ** 2 + ((y - cy) / ry) ** 2 + ((z - cz) / rz) ** 2)
        r_min = np.minimum(r_min, r + 0.15 * noise)
    density = np.clip(GAIN * (1.0 - r_min), 0.0, 1.0)
    density[y < BASE] = 0.0

    grid = vdb.FloatGrid()
    grid.name = "density"
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    grid.saveFloatAsHalf = True
    grid.copyFromArray(density.astype(np.float32), ijk=(0, 0, 0), tolerance=1e-3)
    xf = vdb.createLinearTransform(voxelSize=VOXEL)
    xf.translate(tuple(LOWER[a] + 0.5 * VOXEL for a in range(3)))  # voxel (0,0,0)'s centre
    grid.transform = xf
    grid["units"] = "density in [0, 1]; world space in metres, y up"
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    vdb.write(out, grids=[grid], metadata={"creator": "scripts/make_vdb_cloud.py (seed %d)" % SEED})
    print("%s: %d active voxels of %d, %d bytes" % (out, grid.activeVoxelCount(), density.size, os.path.getsize(out)))


if __name__ == "__main__":
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "content", "clouds", "storm-cell.vdb"))
