#!/usr/bin/python3
"""Writes the .vdb files test_vdb reads, with OpenVDB's own Python bindings (Debian
python3-openvdb): a tool independent of Fulgur, so the import is checked against files the
library itself wrote. Usage: make_vdb_fixtures.py OUTDIR

sparse.vdb   grids "vel" (vec3s), "temperature" (float), "density" (float).
             "density": voxels of 10 units translated by (100, 200, 300); three voxels set
             (0,0,0) = 0.25, (3,1,2) = 1, (5,5,5) = 0.75, and one active tile of 8^3 voxels
             (8..15, 0..7, 0..7) = 0.5: active box (0,0,0)-(15,7,7), everything else 0.
aniso.vdb    "density": voxels of 10 x 10 x 20 units, (0,0,0) = 0.5 and (1,0,1) = 1.
no_density.vdb  "vel" (vec3s), "temperature" and "flame" (float, (0,0,0) = 0.25): no "density".
The others are each one bad case, named by the file.
"""
import os
import sys

import pyopenvdb as vdb


def float_grid(name, background=0.0):
    g = vdb.FloatGrid(background)
    g.name = name
    return g


def main(out):
    os.makedirs(out, exist_ok=True)
    path = lambda name: os.path.join(out, name)

    vel = vdb.Vec3SGrid()
    vel.name = "vel"
    vel.getAccessor().setValueOn((0, 0, 0), (1.0, 0.0, 0.0))
    temperature = float_grid("temperature")
    temperature.getAccessor().setValueOn((0, 0, 0), 0.125)
    density = float_grid("density")
    xf = vdb.createLinearTransform(voxelSize=10.0)
    xf.translate((100.0, 200.0, 300.0))
    density.transform = xf
    acc = density.getAccessor()
    acc.setValueOn((0, 0, 0), 0.25)
    acc.setValueOn((3, 1, 2), 1.0)
    acc.setValueOn((5, 5, 5), 0.75)
    density.fill((8, 0, 0), (15, 7, 7), 0.5, True)  # one leaf-sized block: stored as an active tile
    vdb.write(path("sparse.vdb"), grids=[vel, temperature, density])

    aniso = float_grid("density")
    aniso.transform = vdb.createLinearTransform([[10, 0, 0, 0], [0, 10, 0, 0], [0, 0, 20, 0], [0, 0, 0, 1]])
    aniso.getAccessor().setValueOn((0, 0, 0), 0.5)
    aniso.getAccessor().setValueOn((1, 0, 1), 1.0)
    vdb.write(path("aniso.vdb"), grids=[aniso])

    flame = float_grid("flame")
    flame.getAccessor().setValueOn((0, 0, 0), 0.25)
    vdb.write(path("no_density.vdb"), grids=[vel, temperature, flame])

    # Bad cases.
    with open(path("not_a_vdb.vdb"), "w") as f:
        f.write("this is a text file, not an OpenVDB file\n")
    vdb.write(path("no_float_grid.vdb"), grids=[vel])
    vdb.write(path("empty.vdb"), grids=[float_grid("density")])
    rotated = float_grid("density")
    rotated.transform = vdb.createLinearTransform([[0, 10, 0, 0], [-10, 0, 0, 0], [0, 0, 10, 0], [0, 0, 0, 1]])
    rotated.getAccessor().setValueOn((0, 0, 0), 0.5)
    vdb.write(path("rotated.vdb"), grids=[rotated])
    fog = float_grid("density", 0.1)
    fog.getAccessor().setValueOn((0, 0, 0), 0.5)
    vdb.write(path("background.vdb"), grids=[fog])
    dense = float_grid("density")
    dense.getAccessor().setValueOn((1, 2, 3), 2.0)
    vdb.write(path("out_of_range.vdb"), grids=[dense])
    # One root-level tile of 4096^3 voxels: a few hundred bytes in the file, 2^36 voxels dense.
    huge = float_grid("density")
    huge.fill((0, 0, 0), (4095, 4095, 4095), 0.5, True)
    vdb.write(path("huge.vdb"), grids=[huge])


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: make_vdb_fixtures.py OUTDIR")
    main(sys.argv[1])
