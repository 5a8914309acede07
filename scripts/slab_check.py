#!/usr/bin/python3
"""A homogeneous slab lit by the sun: a third estimate of multiple scattering at a given g,
beside Fulgur's and Cycles' images of the same slab (docs/blender.md, "The day cumulus").

usage:
  scripts/slab_check.py make DIR [--g G]
  scripts/slab_check.py mc [--g G] [--photons N]
  scripts/slab_check.py compare FULGUR.exr [FULGUR_REFERENCE.exr] CYCLES_A.exr CYCLES_B.exr

`make` writes DIR/slab.vdb (a layer 20 x 20 km wide and 2.5 km thick at density 1 on 100 m
voxels, every voxel of its box active) and DIR/slab.json: extinction 0.004 per metre (optical
depth 10, 0.4 per voxel), albedo 0.995, the sun at elevation 32 and azimuth 25 degrees with unit
irradiance, no sky, S on the density's own voxels, and a camera 8 km from the middle of the
layer's top looking down at 35 degrees. Render it with `fulgur-shot DIR/slab.json --time 0
--size 320x180 --internal-scale 1 --exr F.exr --exr-passes --blender B --reference R.png
--against static` and `blender_scene.py B` (two seeds).

`mc` computes the radiance that camera sees in a box of pixels in the middle of the image
(80 x 50 of 320 x 180: the layer's top, 10 km from its edges, i.e. eight transport mean free
paths at g = 0.8), by its own Monte Carlo of an infinite layer: photons enter the top along the
sun, fly exponential steps, keep albedo x their weight at each collision (Russian roulette below
0.05), scatter by Henyey-Greenstein; at every collision the next-event estimate toward each of
5 x 5 pixel directions of the box, w albedo p(cos) exp(-tau to the top / mu) / mu, averaged over
them; 10 batches for the standard error. No grid, no lighting grid, no directions of S. Order
1 is checked against its closed form, albedo p mu0 / (mu0 + mu) (1 - exp(-tau (1/mu0 + 1/mu))).

`compare` prints the mean of the same box of pixels in each image (G channel; Fulgur's
lightning + static + background passes) and each over the Monte Carlo's figure.
"""

import argparse
import json
import math
import pathlib
import sys

import numpy as np

SIGMA, THICKNESS, ALBEDO = 0.004, 2500.0, 0.995
SUN_ELEVATION, SUN_AZIMUTH = 32.0, 25.0
CAMERA = {"target": [0.0, 0.0, 3500.0], "distance": 8000.0, "azimuth": -90.0, "elevation": 35.0, "vertical_fov": 30.0}
WIDTH, HEIGHT, BOX_W, BOX_H = 320, 180, 40, 25  # the box: half-width and half-height in pixels


def make(out, g):
    import pyopenvdb as vdb
    out.mkdir(parents=True, exist_ok=True)
    n, k0, k1 = 200, 9, 37  # index box: 202 x 202 x 28 voxels; density 1 for k in [10, 35)
    a = np.zeros((n + 2, n + 2, k1 - k0), dtype=np.float32)
    a[1:-1, 1:-1, 10 - k0:35 - k0] = 1.0
    grid = vdb.FloatGrid()
    grid.copyFromArray(a, ijk=(-n // 2 - 1, -n // 2 - 1, k0), tolerance=-1.0)  # zeros active too
    grid.transform = vdb.createLinearTransform(voxelSize=100.0)
    grid.name = "density"
    vdb.write(str(out / "slab.vdb"), grids=[grid])
    cam = CAMERA
    scene = {
        "fulgur_scene": 1,
        "name": f"Slab: a homogeneous layer 2.5 km thick (optical depth 10), g = {g}, lit by the sun",
        "camera": {"orbit": {k: cam[k] for k in ("target", "distance", "azimuth", "elevation")},
                   "vertical_fov": cam["vertical_fov"]},
        "medium": {"extinction": SIGMA, "albedo": ALBEDO, "g": g},
        "cloud": {"vdb": "slab.vdb", "grid": "density"},
        "lighting": {"downsample": 1, "directions": 26},
        "transport": {"solver": "lattice_boltzmann", "single_scattering": {"tolerance": 1e-2},
                      "static_light": {"order2_paths": 1600000}},
        "lights": [{"type": "sun", "name": "sun", "elevation": SUN_ELEVATION, "azimuth": SUN_AZIMUTH,
                    "irradiance": 1, "colour": [1, 1, 1]}],
        "effects": {"lightning": False, "single_scattering": True, "multiple_scattering": True, "sun": True,
                    "sky": False, "glow": False},
    }
    (out / "slab.json").write_text(json.dumps(scene, indent=1) + "\n")
    print(json.dumps({"wrote": [str(out / "slab.vdb"), str(out / "slab.json")]}))


def unit(elevation_deg, azimuth_deg):
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def box_directions():
    """Toward the camera from the layer, for 5 x 5 pixels spread over the box."""
    back = unit(CAMERA["elevation"], CAMERA["azimuth"])
    fwd = -back
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    th = math.tan(math.radians(CAMERA["vertical_fov"] / 2))
    out = []
    for py in np.linspace(HEIGHT / 2 - BOX_H + 0.5, HEIGHT / 2 + BOX_H - 0.5, 5):
        for px in np.linspace(WIDTH / 2 - BOX_W + 0.5, WIDTH / 2 + BOX_W - 0.5, 5):
            x, y = (2 * px / WIDTH - 1) * th * WIDTH / HEIGHT, (1 - 2 * py / HEIGHT) * th
            r = fwd + x * right + y * up
            out.append(-r / np.linalg.norm(r))
    return np.array(out)


def hg(g, c):
    return (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * c) ** 1.5)


def mc(g, photons, batches=10, seed=7):
    rng = np.random.default_rng(seed)
    d0 = -unit(SUN_ELEVATION, SUN_AZIMUTH)
    V = box_directions()

    def scatter(d):
        n = d.shape[0]
        if g == 0.0:
            ct = 1 - 2 * rng.random(n)
        else:
            s = (1 - g * g) / (1 - g + 2 * g * rng.random(n))
            ct = np.clip((1 + g * g - s * s) / (2 * g), -1, 1)
        st = np.sqrt(np.maximum(0, 1 - ct * ct))
        ph = 2 * math.pi * rng.random(n)
        a = np.where(np.abs(d[:, 2:3]) < 0.9, np.array([[0, 0, 1.0]]), np.array([[1.0, 0, 0]]))
        t1 = np.cross(a, d)
        t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
        t2 = np.cross(d, t1)
        return ct[:, None] * d + st[:, None] * (np.cos(ph)[:, None] * t1 + np.sin(ph)[:, None] * t2)

    per_batch = []
    n = photons // batches
    for _ in range(batches):
        z = np.full(n, THICKNESS)
        d = np.tile(d0, (n, 1))
        w = np.ones(n)
        order = np.zeros(n, dtype=int)
        alive = np.ones(n, dtype=bool)
        acc = np.zeros(2)  # order 1, orders >= 2
        while alive.any():
            idx = np.nonzero(alive)[0]
            z[idx] += -np.log(1 - rng.random(idx.size)) / SIGMA * d[idx, 2]
            out = (z[idx] > THICKNESS) | (z[idx] < 0)
            alive[idx[out]] = False
            idx = idx[~out]
            if idx.size == 0:
                break
            order[idx] += 1
            c = d[idx] @ V.T
            est = (w[idx, None] * ALBEDO * hg(g, c) * np.exp(-SIGMA * (THICKNESS - z[idx, None]) / V[None, :, 2])
                   / V[None, :, 2]).mean(axis=1)
            first = order[idx] == 1
            acc[0] += est[first].sum()
            acc[1] += est[~first].sum()
            w[idx] *= ALBEDO
            d[idx] = scatter(d[idx])
            low = w[idx] < 0.05
            if low.any():
                k = idx[low]
                survive = rng.random(k.size) < 0.5
                w[k[survive]] *= 2
                alive[k[~survive]] = False
        per_batch.append(acc / n * abs(d0[2]))  # unit irradiance: abs(d0.z) per unit of the top
    b = np.array(per_batch)
    mean, se = b.mean(axis=0), b.std(axis=0, ddof=1) / math.sqrt(batches)
    # Order 1 in closed form, averaged over the same directions.
    mu0, tau = abs(d0[2]), SIGMA * THICKNESS
    closed = np.mean([ALBEDO * hg(g, float(d0 @ v)) * mu0 / (mu0 + v[2]) * (1 - math.exp(-tau * (1 / mu0 + 1 / v[2])))
                      for v in V])
    return {"g": g, "photons": photons, "single": mean[0], "single_se": se[0], "single_closed_form": closed,
            "multiple": mean[1], "multiple_se": se[1], "total": float(mean.sum()),
            "total_se": float(math.sqrt((se ** 2).sum()))}


def box_mean(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(str(path))
    img = buf.get_pixels(oiio.FLOAT)
    names = list(buf.spec().channelnames)
    h, w = img.shape[:2]
    if (h, w) != (HEIGHT, WIDTH):
        raise SystemExit(f"{path}: {w}x{h}, expected {WIDTH}x{HEIGHT}")
    box = img[h // 2 - BOX_H:h // 2 + BOX_H, w // 2 - BOX_W:w // 2 + BOX_W]
    if "static.G" in names:
        g = sum(box[:, :, names.index(f"{p}.G")] for p in ("lightning", "static", "background") if f"{p}.G" in names)
    else:
        g = box[:, :, 1]
    return float(g.mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("dir", type=pathlib.Path)
    m.add_argument("--g", type=float, default=0.8)
    c = sub.add_parser("mc")
    c.add_argument("--g", type=float, default=0.8)
    c.add_argument("--photons", type=float, default=2e6)
    p = sub.add_parser("compare")
    p.add_argument("images", nargs="+", type=pathlib.Path)
    p.add_argument("--mc", type=float, help="the Monte Carlo's total (from `mc`) to divide by")
    a = ap.parse_args()
    if a.cmd == "make":
        if not -1 < a.g < 1:
            raise SystemExit("--g: must lie in (-1, 1)")
        make(a.dir, a.g)
    elif a.cmd == "mc":
        if not -1 < a.g < 1 or a.photons < 1000:
            raise SystemExit("--g in (-1, 1), --photons >= 1000")
        print(json.dumps(mc(a.g, int(a.photons))))
    else:
        out = {str(i): box_mean(i) for i in a.images}
        if a.mc:
            out.update({f"{i} / mc": v / a.mc for i, v in list(out.items())})
        print(json.dumps(out))


if __name__ == "__main__":
    sys.exit(main())
