#!/usr/bin/python3
"""How large Cycles' sphere lights may be when they stand for Fulgur's channel inside a cloud
(docs/blender.md, "The channel's points in Cycles").

usage:
  scripts/cycles_light_radius.py DIR [--max-loss F] [--radius M ...]

DIR is what `fulgur-shot ... --blender DIR` writes (frame.json, density.vdb). Prints one JSON
line: the fraction of the lights' power that collides in the medium at all, and for each radius
tried the power the first collisions receive from Cycles' sphere lights over what they receive
from true points; `radius` is the largest radius on the ladder (half the points' spacing, halved
until it qualifies) whose loss is at most --max-loss (default 0.01).

Why it matters. A Cycles 3.4 point light of radius r > 0 is sampled as a disk of radius r that
faces the shading point (point_light_sample), which makes what it delivers at a distance d from
its centre

  I 2 (1 - d / sqrt(d^2 + r^2)) / r^2      instead of a point's      I / d^2:

the same a few r away, bounded near it. Light that the channel sends into the cloud around it
then collides less within a few r of the channel, and that first collision is where all the
scattered light of the frame comes from; nothing makes up for it (the disk does not emit the
difference elsewhere). In a cloud whose mean free path near the channel is tens of metres, a
radius of 15 m loses a sixth of the first collisions and Cycles renders the cloud a sixth too dark
(measured, docs/blender.md). True points (r = 0) have no bias but an infinite variance (1/d^2
near the light), so the comparison wants the largest radius whose loss is negligible.

How it is measured: the density read piecewise constant (as Fulgur's truth transports light),
straight rays from each light in `directions` directions (a Fibonacci sphere) cut into `steps`
pieces whose lengths grow geometrically from 1e-3 of the smallest radius to the grid's diagonal;
a piece collides exp(-tau_in) - exp(-tau_out) of the ray's power, weighted by the disk's
d^2 2 (1 - d / sqrt(d^2 + r^2)) / r^2 at its middle. At most `max_lights` lights, evenly spaced
along the list, each standing for the intensity of those it skips.
"""

import json
import math
import pathlib
import sys

import numpy as np


def disk_over_point(d, r):
    """What Cycles' disk light of radius r delivers at distance d, over a point light's: written
    as 2 d^2 / (s (s + d)), s = sqrt(d^2 + r^2), which is exact and stable for d >> r."""
    if r <= 0.0:
        return np.ones_like(d)
    s = np.sqrt(d * d + r * r)
    return 2.0 * d * d / (s * (s + d))


def first_collision_ratios(rho, origin, voxel, extinction, positions, intensities, radii, directions=400,
                           steps=1200, max_lights=64):
    """(collided fraction of the lights' power, [disk / point of the first collisions per radius])."""
    rho = np.asarray(rho, np.float32)
    dims = np.array(rho.shape)
    origin = np.asarray(origin, float)
    positions = np.asarray(positions, float)
    intensities = np.asarray(intensities, float)
    keep = intensities > 0.0
    positions, intensities = positions[keep], intensities[keep]
    if len(positions) == 0:
        raise ValueError("no light with a positive intensity")
    # Every k-th light standing for the k lights from it (the channel's points are evenly spaced).
    k = max(1, int(math.ceil(len(positions) / max_lights)))
    weights = np.add.reduceat(intensities, np.arange(0, len(intensities), k))
    positions = positions[::k]
    i = np.arange(directions) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / directions)
    azimuth = math.pi * (1.0 + 5.0 ** 0.5) * i
    dirs = np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], -1)
    positive = [r for r in radii if r > 0.0]
    near = 1e-3 * min(positive) if positive else 1e-3 * voxel
    far = float(np.linalg.norm(dims * voxel)) + 1.0
    edges = np.concatenate([[0.0], np.geomspace(near, far, steps)])
    mid, length = 0.5 * (edges[1:] + edges[:-1]), np.diff(edges)
    kernels = [disk_over_point(mid, r) for r in radii]
    collided, received = 0.0, np.zeros(len(radii))
    for p, w in zip(positions, weights):
        x = p[None, None, :] + dirs[:, None, :] * mid[None, :, None]
        cell = np.floor((x - origin) / voxel).astype(np.int64)
        inside = np.all((cell >= 0) & (cell < dims), -1)
        cell = np.clip(cell, 0, dims - 1)
        sigma = extinction * np.where(inside, rho[cell[..., 0], cell[..., 1], cell[..., 2]], 0.0)
        tau_out = np.cumsum(sigma * length, 1)
        pieces = (np.exp(-(tau_out - sigma * length)) - np.exp(-tau_out)).sum(0) / directions
        collided += w * pieces.sum()
        received += w * np.array([(pieces * kern).sum() for kern in kernels])
    total = weights.sum()
    if collided <= 0.0:
        return 0.0, [1.0] * len(radii)
    return collided / total, list(received / collided)


def ladder(spacing, rungs=12):
    """Half the points' spacing (a tube around the channel), then halved each rung."""
    return [0.5 * spacing / 2.0 ** n for n in range(rungs)]


def choose(medium, positions, intensities, spacing, rho, max_loss=0.01, radii=None):
    """The largest radius on the ladder (or of `radii`) whose first-collision loss is at most
    max_loss, and the figures behind it; 0 (true points) when none qualifies. `medium`: frame.json's
    medium (origin, voxel_size, extinction) or None; `rho` its density, indexed [i, j, k]."""
    radii = sorted(radii if radii else ladder(spacing), reverse=True)
    if medium is None or not any(i > 0.0 for i in intensities):
        return {"radius": radii[0], "loss": 0.0, "max_loss": max_loss, "collided_fraction": 0.0, "ladder": {}}
    fraction, ratios = first_collision_ratios(rho, medium["origin"], medium["voxel_size"], medium["extinction"],
                                              positions, intensities, radii)
    chosen, loss = 0.0, 0.0
    for r, q in zip(radii, ratios):
        if 1.0 - q <= max_loss:
            chosen, loss = r, 1.0 - q
            break
    return {"radius": chosen, "loss": loss, "max_loss": max_loss, "collided_fraction": fraction,
            "ladder": {"%g" % r: 1.0 - q for r, q in zip(radii, ratios)}}


def main(argv):
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from exact_single_scattering import load

    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    directory, max_loss, radii = argv[0], 0.01, []
    i = 1
    while i < len(argv):
        if argv[i] in ("--max-loss", "--radius") and i + 1 < len(argv):
            try:
                v = float(argv[i + 1])
            except ValueError:
                raise SystemExit(f"{argv[i]}: expected a number, got '{argv[i + 1]}'")
            if not (math.isfinite(v) and v >= 0.0):
                raise SystemExit(f"{argv[i]}: {argv[i + 1]} is not a finite number >= 0")
            if argv[i] == "--max-loss":
                max_loss = v
            else:
                radii.append(v)
            i += 2
        else:
            raise SystemExit(f"unknown or incomplete option '{argv[i]}'\n{__doc__}")
    frame, rho = load(directory)
    lights = frame["lights"]
    print(json.dumps(choose(frame["medium"], [l["position"] for l in lights], [l["intensity"] for l in lights],
                            frame["light_spacing"], rho, max_loss, radii or None)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
