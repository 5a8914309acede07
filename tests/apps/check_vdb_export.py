#!/usr/bin/python3
"""Checks a .vdb written by fulgur-bake --vdb or fulgur-shot --vdb with OpenVDB's own Python
bindings (python3-openvdb), as a user's tool would read it: the grids' names, their
metadata (units, directions, scene), the transforms in metres and a lit S.
Usage: check_vdb_export.py FILE.vdb DIRECTIONS DENSITY_VOXEL_METRES LIGHTING_VOXEL_METRES"""
import sys

import pyopenvdb as vdb


def main(path, directions, density_voxel, lighting_voxel):
    grids = {g.name: g for g in vdb.readAllGridMetadata(path)}
    expected = ["density"] + ["S_%02d" % m for m in range(directions)]
    assert sorted(grids) == sorted(expected), "grids %s, expected %s" % (sorted(grids), sorted(expected))
    density = grids.pop("density")
    assert density.gridClass == vdb.GridClass.FOG_VOLUME, density.gridClass
    assert density["fulgur_extinction"] > 0.0
    assert density.transform.voxelSize()[0] == density_voxel, density.transform.voxelSize()
    for g in grids.values():
        assert g["fulgur_units"] == "W m^-2 sr^-1", g["fulgur_units"]
        d = g["fulgur_direction"]
        assert abs(d[0] ** 2 + d[1] ** 2 + d[2] ** 2 - 1.0) < 1e-9, d  # unit, to double rounding
        assert g.transform.voxelSize()[0] == lighting_voxel, g.transform.voxelSize()
    assert "fulgur_scene" in vdb.readMetadata(path)
    lo, hi = vdb.read(path, "S_00").evalMinMax()
    assert hi > 0.0, "S_00 is dark (%g..%g)" % (lo, hi)
    print("%s: density and %d S grids, S_00 in [%g, %g]" % (path, len(grids), lo, hi))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]))
