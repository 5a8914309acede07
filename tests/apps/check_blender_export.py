#!/usr/bin/python3
"""Checks what fulgur-shot --blender wrote for a frame with rain, as Blender's script reads it
(frame.json, the VDBs through OpenVDB's own Python bindings): the rain as a medium of its own on
the density's grid (extinction 1: the grid is sigma_t per metre), its grid's transform the
density's, its largest value frame.json's max_extinction, no rain above its top; and, for the
same frame with the rain switched off, no rain at all (no entry, no file).
Usage: check_blender_export.py WET_DIR DRY_DIR"""
import json
import os
import sys

import numpy as np
import pyopenvdb as vdb


def main(wet, dry):
    with open(os.path.join(wet, "frame.json"), encoding="utf-8") as f:
        frame = json.load(f)
    m, r = frame["medium"], frame["rain"]
    assert r is not None, "the frame draws rain: frame.json's rain is null"
    assert r["file"] == "rain.vdb" and r["grid"] == "rain", r
    assert r["extinction"] == 1.0, r["extinction"]
    assert 0.0 < r["albedo"] <= 1.0 and -1.0 < r["g"] < 1.0, r
    for k in ("voxel_size", "origin", "dims"):
        assert r[k] == m[k], "rain.%s %s differs from medium.%s %s" % (k, r[k], k, m[k])
    grid = vdb.read(os.path.join(wet, "rain.vdb"), "rain")
    assert grid.valueTypeName == "float", grid.valueTypeName
    vs = r["voxel_size"]
    assert abs(grid.transform.voxelSize()[0] - vs) <= 1e-9 * vs, grid.transform.voxelSize()
    c0 = grid.transform.indexToWorld((0, 0, 0))
    want = [o + 0.5 * vs for o in r["origin"]]
    assert all(abs(a - b) <= 1e-6 * vs for a, b in zip(c0, want)), (c0, want)
    values = np.zeros(tuple(r["dims"]), np.float32)
    grid.copyToArray(values, ijk=(0, 0, 0))
    hi = float(values.max())
    # The grid holds the field's float32 values; max_extinction is the same maximum in double.
    assert abs(hi - r["max_extinction"]) <= 1e-6 * r["max_extinction"], (hi, r["max_extinction"])
    assert float(values.min()) >= 0.0, values.min()
    # No rain in voxels wholly above its top (the cloud's base over the raining columns).
    first_above = int(np.ceil((r["top"] - r["origin"][2]) / vs))
    assert not values[:, :, first_above:].any(), "rain above its top (%g m)" % r["top"]
    raining = int((values > 0.0).sum())
    assert raining > 0, "no rain in rain.vdb"

    with open(os.path.join(dry, "frame.json"), encoding="utf-8") as f:
        assert json.load(f)["rain"] is None, "the rain switched off is still exported"
    assert not os.path.exists(os.path.join(dry, "rain.vdb")), "rain.vdb written with the rain off"
    print("%s: rain on %d voxels up to %g m, sigma_t up to %g /m; %s: none" % (wet, raining, r["top"], hi, dry))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
