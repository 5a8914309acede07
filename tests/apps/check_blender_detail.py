#!/usr/bin/python3
"""Checks what fulgur-shot --blender writes for a scene with sub-voxel detail, as Blender's script
reads it (frame.json, the VDB through OpenVDB's own Python bindings): the density Cycles renders
is the one the march draws, so with the billows on it is the eroded field on a finer grid over
the same box (cloud::detailed_on_finer_grid: here 2x, the finest billow 500 m over 500 m voxels),
and with `--off detail` the density before the detail on the scene's own grid. Erosion only
removes density: the finer grid lies at or under the undetailed density interpolated at its
centres (Grid3::sample's clamped trilinear), is empty where that is, and has lost a visible share
of its mass (measured 0.66 kept; without the erosion all of it). The rain keeps the scene's grid.
Usage: check_blender_detail.py FULGUR_SHOT SCENE.json WORK_DIR"""
import json
import os
import subprocess
import sys

import numpy as np
import pyopenvdb as vdb


def read(directory):
    with open(os.path.join(directory, "frame.json"), encoding="utf-8") as f:
        frame = json.load(f)
    m = frame["medium"]
    grid = vdb.read(os.path.join(directory, "density.vdb"), "density")
    vs = m["voxel_size"]
    assert abs(grid.transform.voxelSize()[0] - vs) <= 1e-9 * vs, (grid.transform.voxelSize(), vs)
    values = np.zeros(tuple(m["dims"]), np.float32)
    grid.copyToArray(values, ijk=(0, 0, 0))
    return frame, values


def trilinear(values, origin, vs, points):
    """Grid3::sample: voxel centres at origin + (i + 0.5) vs, clamped to the outermost centres."""
    u = (points - np.asarray(origin)) / vs - 0.5
    out = np.zeros(points.shape[:-1])
    dims = np.asarray(values.shape)
    u = np.clip(u, 0.0, dims - 1)
    i0 = np.minimum(np.floor(u).astype(int), dims - 1)
    i1 = np.minimum(i0 + 1, dims - 1)
    f = u - i0
    for cz in (0, 1):
        for cy in (0, 1):
            for cx in (0, 1):
                w = ((f[..., 0] if cx else 1 - f[..., 0]) * (f[..., 1] if cy else 1 - f[..., 1])
                     * (f[..., 2] if cz else 1 - f[..., 2]))
                ix = i1[..., 0] if cx else i0[..., 0]
                iy = i1[..., 1] if cy else i0[..., 1]
                iz = i1[..., 2] if cz else i0[..., 2]
                out += w * values[ix, iy, iz]
    return out


def main(shot, scene_path, work):
    os.makedirs(work, exist_ok=True)
    with open(scene_path, encoding="utf-8") as f:
        scene = json.load(f)
    scene["cloud"]["detail"] = {"seed": 7, "scale": 1000, "octaves": 2, "strength": 0.6}
    path = os.path.join(work, "scene.json")
    with open(path, "w", encoding="utf-8") as f:
        json.dump(scene, f)
    for name, extra in (("detail", []), ("undetailed", ["--off", "detail"])):
        subprocess.run([shot, path, "--seed", "1", "--time", "0", "--size", "32x18",
                        "-o", os.path.join(work, name + ".png"), "--blender", os.path.join(work, name)] + extra,
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    fine_frame, fine = read(os.path.join(work, "detail"))
    coarse_frame, coarse = read(os.path.join(work, "undetailed"))
    fm, cm = fine_frame["medium"], coarse_frame["medium"]
    assert cm["voxel_size"] == 500 and cm["dims"] == [32, 32, 16], cm
    assert fm["voxel_size"] == 250 and fm["dims"] == [64, 64, 32], fm
    assert fm["origin"] == cm["origin"], (fm["origin"], cm["origin"])
    for frame in (fine_frame, coarse_frame):
        r = frame["rain"]
        assert r is not None and r["voxel_size"] == 500 and r["dims"] == [32, 32, 16], r
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in fine.shape], indexing="ij"), axis=-1)
    centres = np.asarray(fm["origin"]) + (idx + 0.5) * fm["voxel_size"]
    under = trilinear(coarse, cm["origin"], cm["voxel_size"], centres)
    assert float(fine.min()) >= 0.0, fine.min()
    # At or under the undetailed field (float rounding of the erosion's division: 1e-6).
    over = float((fine - under).max())
    assert over <= 1e-6, "the detailed density exceeds the undetailed one by %g" % over
    assert not np.any((under == 0) & (fine != 0)), "density where the undetailed cloud has none"
    kept = float(fine.sum() / under.sum())
    assert 0.5 < kept < 0.95, "the erosion kept %g of the mass" % kept
    print(json.dumps({"name": "check-blender-detail", "refine": 2, "mass_kept": kept, "largest_excess": over}))


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
