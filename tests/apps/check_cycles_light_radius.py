#!/usr/bin/python3
"""scripts/cycles_light_radius.py against a closed form: one light at the centre of a uniform
cube thick enough to be an infinite medium.

The cube: 40^3 voxels of 50 m, density 1, extinction 0.01 per metre, so every ray from the
centre crosses an optical depth of at least 10 before it leaves (e^-10 = 4.5e-5 of the power
escapes, from the far field where a disk and a point deliver the same). In an infinite uniform
medium of extinction sigma the first collisions that a Cycles sphere light of radius r feeds,
over what a true point feeds, are

  R(a) = integral over x in [0, inf) of e^-x 2 x^2 / (s (s + x)) dx,   s = sqrt(x^2 + a^2),  a = sigma r,

integrated here on a uniform grid of 4M points over x in [0, 60] (trapezoid: its error is below
1e-7 at these a, checked against 8M points). The script instead sums the exact collision
probability of each of 1200 geometrically growing pieces of 400 rays, each weighted by the disk
at its middle: within 5e-7 of R (measured). The bound, 1e-3, is a tenth of the 1% loss the
script is used to guarantee and far below what a wrong kernel would do: the solid angle form
r^2 / (r^2 + d^2) in place of the disk's is 0.046 off at a = 0.5, a point (no kernel) 0.38.
The radius chooser must pick the largest rung of its ladder whose loss is within the bound it
is given, and the rung above must exceed it.
"""

import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "scripts"))
import cycles_light_radius as clr  # noqa: E402

SIGMA, N, VOXEL = 0.01, 40, 50.0


def closed_form(a):
    x = np.linspace(0.0, 60.0, 4_000_001)
    s = np.sqrt(x * x + a * a)
    f = np.exp(-x) * 2.0 * x * x / (s * (s + x))
    return float((f.sum() - 0.5 * (f[0] + f[-1])) * (x[1] - x[0]))


def main():
    rho = np.ones((N, N, N), np.float32)
    origin = [-0.5 * N * VOXEL] * 3
    failures = []
    radii = [2.0, 10.0, 50.0]  # a = 0.02, 0.1, 0.5
    fraction, ratios = clr.first_collision_ratios(rho, origin, VOXEL, SIGMA, [[0.0, 0.0, 0.0]], [1e6], radii)
    if abs(fraction - 1.0) > 1e-4:
        failures.append(f"collided fraction {fraction:.6f}, expected 1 - 4.5e-5")
    for r, got in zip(radii, ratios):
        want = closed_form(SIGMA * r)
        err = abs(got - want)
        print(f"r {r:5.1f} m (sigma r {SIGMA * r:.2f}): script {got:.6f}, closed form {want:.6f}, |diff| {err:.2e}")
        if not err <= 1e-3:
            failures.append(f"radius {r}: {got:.6f} against {want:.6f}")
    # The chooser: the light 500 m off the centre along x, spacing 40 m (ladder 20, 10, 5, ...).
    pick = clr.choose({"origin": origin, "voxel_size": VOXEL, "extinction": SIGMA}, [[500.0, 0.0, 0.0]], [1e6],
                      40.0, rho, max_loss=0.01)
    rungs = sorted(((float(k), v) for k, v in pick["ladder"].items()), reverse=True)
    above = [v for r, v in rungs if r > pick["radius"]]
    print(f"chosen radius {pick['radius']} m, loss {pick['loss']:.4f}; the rung above loses "
          f"{above[-1] if above else float('nan'):.4f}")
    if not (pick["loss"] <= 0.01 and above and above[-1] > 0.01 and pick["radius"] > 0.0):
        failures.append(f"chooser: {pick}")
    if any(b < a for (_, a), (_, b) in zip(rungs[1:], rungs)):
        failures.append(f"loss does not shrink with the radius: {rungs}")
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
