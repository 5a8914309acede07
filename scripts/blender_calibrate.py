#!/usr/bin/python3
"""Checks scripts/blender_scene.py (Blender Cycles as Fulgur's reference) against analytic cases.

    /usr/bin/python3 scripts/blender_calibrate.py [--keep DIR] [--blender blender]

Each case writes a frame.json (and a VDB made with pyopenvdb) into a temporary directory, runs
`blender -b --factory-startup --python scripts/blender_scene.py -- DIR --out OUT.exr`, reads the
EXR (scripts/exr_tools.py) and prints one JSON line: measured vs analytic.

 1. absorption: a homogeneous box (albedo 0) in front of a uniform sky of radiance 1, seen
    along z and along x from 3 km: pixel = exp(-integral of sigma_t) (per pixel, integrated in
    numpy through the trilinearly interpolated grid under frame.json's voxel convention, averaged
    over the pixel). Rendered first without the script's half-voxel correction
    (FULGUR_BLENDER_VOXEL_SHIFT=0) to measure Cycles' offset from the centroid of the shadow,
    then with it: the offset must be ~0 and the pixels must match.
 2. single scattering: a point light above an optically thin (tau ~ 0.003) homogeneous cube,
    g = 0, albedo 1, flash_colour (0.5, 1, 2) (folded into the power by the script): pixel =
    integral sigma_s T I flash / (4 pi r^2) dt along the camera ray. Checks the 4 pi of the
    point light's power and the colour folding.
 3. sky: no volume; a camera looking up and one looking at the horizon: pixel =
    mix(horizon, zenith, sqrt(clamp(d.z, 0, 1))) averaged over the pixel.
 4. sun + ground: a Lambertian ground (albedo 0.5) under a sun 60 degrees from the zenith
    (pixel = a E cos / pi), first with a sky that lights nothing (lights_cloud false), then with
    one that lights the ground (+ a (h + 0.8 (z - h)), the cosine-weighted sky integral).
 5. white furnace: a conservative cube (albedo 1, g 0.85, optical depth ~3) under a uniform sky
    of 1: every pixel is exactly 1 when the sky lights the cloud (needs all scattering orders:
    with Cycles' default volume_bounces 0 the cube comes out 0.54), exp(-tau) when it does not.
 6. errors: a missing field, a missing VDB, a bad type, no frame.json: exit status 1 and a
    message naming the file and the field.

The single-scattering case is also rendered without blender_scene.py's density scale
(FULGUR_BLENDER_DENSITY_SCALE=1) to show Cycles' 1e-5 /m cutoff, and the absorption case
without its half-voxel correction (FULGUR_BLENDER_VOXEL_SHIFT=0) to measure Cycles' offset.
Renders are 32x32 with 16-1024 samples (1.5-11 s of wall time each on 2 cores, mostly Blender's
start-up; about a minute for all cases, the numpy references included).
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
import pyopenvdb as vdb

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from exr_tools import read_exr  # noqa: E402

SCENE_SCRIPT = os.path.join(HERE, "blender_scene.py")
W = H = 32


# ------------------------------------------------------------------------------------------
# Writing cases and running Blender
# ------------------------------------------------------------------------------------------

def write_vdb(path, rho, voxel_size, origin, name="density"):
    """rho[i, j, k] is voxel (i, j, k), centred at origin + (i + 0.5, j + 0.5, k + 0.5) * voxel_size.
    Voxels are set one by one (no copyFromArray: it makes constant blocks into tiles, which
    Cycles 3.4 renders as empty)."""
    grid = vdb.FloatGrid()
    grid.name = name
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    acc = grid.getAccessor()
    for ijk in zip(*np.nonzero(rho)):
        acc.setValueOn(tuple(int(v) for v in ijk), float(rho[ijk]))
    xf = vdb.createLinearTransform(voxelSize=voxel_size)
    xf.translate(tuple(o + 0.5 * voxel_size for o in origin))
    grid.transform = xf
    vdb.write(path, grids=[grid])


def frame(camera, medium=None, lights=(), flash=(1.0, 1.0, 1.0), sun=None, sky=None, ground=None):
    return {"format": "fulgur-blender-frame", "version": 1, "scene": "blender_calibrate.py",
            "units": {"length": "m", "radiance": "W m^-2 sr^-1", "intensity": "W sr^-1",
                      "irradiance": "W m^-2"},
            "image": {"width": W, "height": H}, "camera": camera, "medium": medium,
            "flash_colour": list(flash),
            "lights": [{"position": list(p), "intensity": i} for p, i in lights],
            "sun": sun, "sky": sky, "ground": ground}


def render(root, name, fr, rho=None, samples=16, seed=1, env=None, blender="blender"):
    d = os.path.join(root, name)
    os.makedirs(d, exist_ok=True)
    if rho is not None:
        m = fr["medium"]
        write_vdb(os.path.join(d, m["file"]), rho, m["voxel_size"], m["origin"], m["grid"])
    with open(os.path.join(d, "frame.json"), "w") as f:
        json.dump(fr, f, indent=1)
    out = os.path.join(root, name + ".exr")
    cmd = [blender, "-b", "--factory-startup", "--python", SCENE_SCRIPT, "--", d, "--out", out,
           "--samples", str(samples), "--seed", str(seed), "--threads", "2"]
    e = dict(os.environ)
    e.update(env or {})
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=e)
    wall = time.monotonic() - t0
    line = [l for l in p.stdout.splitlines() if l.startswith('{"name":"blender-scene"')]
    if p.returncode != 0 or not line:
        sys.stderr.write(p.stdout[-3000:] + p.stderr[-3000:])
        raise RuntimeError("%s: blender failed (status %d)" % (name, p.returncode))
    info = json.loads(line[-1])
    info["wall_seconds"] = round(wall, 2)
    img, _ = read_exr(out)
    return img, info


# ------------------------------------------------------------------------------------------
# Analytic side
# ------------------------------------------------------------------------------------------

def camera_rays(cam, sub):
    """Unit directions (H, W, sub*sub, 3) of a sub x sub grid of rays in each pixel (row 0 = top)."""
    pos = np.array(cam["position"], float)
    fwd = np.array(cam["target"], float) - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.array(cam["up"], float))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    t = math.tan(math.radians(cam["vertical_fov_deg"]) / 2.0)
    o = (np.arange(sub) + 0.5) / sub
    px = (np.arange(W)[:, None] + o[None, :]).reshape(-1)            # W*sub
    py = (np.arange(H)[:, None] + o[None, :]).reshape(-1)            # H*sub
    sx = (px / W * 2.0 - 1.0) * t * W / H
    sy = (1.0 - py / H * 2.0) * t
    d = fwd + sx[None, :, None] * right + sy[:, None, None] * up     # (H*sub, W*sub, 3)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d = d.reshape(H, sub, W, sub, 3).transpose(0, 2, 1, 3, 4).reshape(H, W, sub * sub, 3)
    return pos, d, right, up


def trilinear(rho, p, origin, vs, shift=0.0):
    """rho trilinearly interpolated at points p (..., 3), voxel centres at origin + (ijk + 0.5 +
    shift) * vs, zero outside the grid."""
    pad = np.pad(rho, 1)
    q = (p - np.asarray(origin)) / vs - 0.5 - shift + 1.0
    i0 = np.floor(q).astype(np.int64)
    f = q - i0
    val = np.zeros(p.shape[:-1])
    for c in range(8):
        o = np.array([(c >> 0) & 1, (c >> 1) & 1, (c >> 2) & 1])
        idx = i0 + o
        ok = np.all((idx >= 0) & (idx < np.array(pad.shape)), axis=-1)
        idx = np.where(ok[..., None], idx, 0)
        w = np.prod(np.where(o == 1, f, 1.0 - f), axis=-1)
        val += np.where(ok, w * pad[idx[..., 0], idx[..., 1], idx[..., 2]], 0.0)
    return val


def box_chord(pos, d, lo, hi):
    """Entry and exit distances of rays pos + t d through the box [lo, hi] (tmax < tmin: a miss)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (np.asarray(lo) - pos) * inv
        t2 = (np.asarray(hi) - pos) * inv
    tmin = np.nanmax(np.minimum(t1, t2), axis=-1).clip(min=0.0)
    tmax = np.nanmin(np.maximum(t1, t2), axis=-1)
    return tmin, tmax


def optical_depth_image(cam, rho, origin, vs, ext, shift, sub=3, steps=200):
    pos, d, _, _ = camera_rays(cam, sub)
    n = np.array(rho.shape)
    lo = np.asarray(origin) + (shift - 1.0) * vs
    hi = np.asarray(origin) + (n + shift + 1.0) * vs
    tmin, tmax = box_chord(pos, d, lo, hi)
    length = np.maximum(tmax - tmin, 0.0)
    u = (np.arange(steps) + 0.5) / steps
    tau = np.zeros(d.shape[:-1])
    for r in range(H):  # one image row at a time keeps the arrays small
        t = tmin[r][..., None] + length[r][..., None] * u           # (W, sub2, steps)
        p = pos + d[r][:, :, None, :] * t[..., None]
        tau[r] = ext * trilinear(rho, p, origin, vs, shift).sum(-1) * length[r] / steps
    return tau                                                         # (H, W, sub2)


def transmittance_image(cam, rho, origin, vs, ext, shift):
    return np.exp(-optical_depth_image(cam, rho, origin, vs, ext, shift)).mean(-1)


def shadow_centroid(img, cam, right, up, distance):
    """World-space centroid (relative to the image centre, on the plane through the target) of
    the absorbance 1 - T."""
    a = 1.0 - img
    ys, xs = np.mgrid[0:H, 0:W]
    px = 2.0 * distance * math.tan(math.radians(cam["vertical_fov_deg"]) / 2.0) / H  # metres/pixel
    cx = ((xs + 0.5 - W / 2) * a).sum() / a.sum() * px
    cy = ((H / 2 - ys - 0.5) * a).sum() / a.sum() * px
    return cx * right + cy * up


def emit(rec):
    print(json.dumps(rec, separators=(",", ":")))
    sys.stdout.flush()


# ------------------------------------------------------------------------------------------
# Cases
# ------------------------------------------------------------------------------------------

def case_absorption(root, blender):
    vs, origin, ext = 10.0, (-83.0, -71.0, -97.0), 0.02
    rho = np.zeros((16, 16, 16))
    box = (slice(5, 11), slice(4, 9), slice(6, 10))  # 6 x 5 x 4 voxels
    rho[box] = 1.0
    lo_idx = np.array([5, 4, 6])
    hi_idx = np.array([11, 9, 10])
    centre = np.asarray(origin) + 0.5 * (lo_idx + hi_idx) * vs   # file convention
    medium = {"file": "box.vdb", "grid": "density", "extinction": ext, "albedo": 0.0, "g": 0.0,
              "voxel_size": vs, "origin": list(origin), "dims": [16, 16, 16]}
    sky = {"zenith_rgb": [1, 1, 1], "horizon_rgb": [1, 1, 1], "lights_cloud": True}
    dist = 3000.0
    fov = math.degrees(2.0 * math.atan(60.0 / dist))            # 120 m across at the box
    views = {
        "z": ({"position": list(centre + [0, 0, dist]), "target": list(centre), "up": [0, 1, 0],
               "vertical_fov_deg": fov}, 4),                     # looks down -z through 4 voxels
        "x": ({"position": list(centre + [dist, 0, 0]), "target": list(centre), "up": [0, 0, 1],
               "vertical_fov_deg": fov}, 6),                     # looks along -x through 6 voxels
    }
    results, refs = {}, {}
    for mode, env in (("raw", {"FULGUR_BLENDER_VOXEL_SHIFT": "0"}), ("corrected", None)):
        for axis, (cam, nvox) in views.items():
            fr = frame(cam, medium=medium, sky=sky)
            img, info = render(root, "absorption_%s_%s" % (mode, axis), fr, rho, samples=16, env=env,
                               blender=blender)
            T = img[:, :, :3].mean(-1)
            _, _, right, up = camera_rays(cam, 1)
            if axis not in refs:  # references for Cycles' voxel centres at +s voxels
                refs[axis] = {s: transmittance_image(cam, rho, origin, vs, ext, s) for s in (-0.5, 0.0, 0.5)}
            ref = refs[axis]
            offset = (shadow_centroid(T, cam, right, up, dist)
                      - shadow_centroid(ref[0.0], cam, right, up, dist)) / vs   # voxels
            mid = slice(H // 2 - 1, H // 2 + 1)
            centre_px = float(T[mid, mid].mean())
            analytic = math.exp(-ext * nvox * vs)
            results[(mode, axis)] = offset
            emit({"case": "absorption", "mode": mode, "view": "along -" + axis,
                  "centre_pixel": round(centre_px, 5), "analytic_exp_minus_tau": round(analytic, 5),
                  "rel_err": round(centre_px / analytic - 1.0, 7),
                  "shadow_offset_voxels_xyz": [round(float(v), 3) for v in offset],
                  "rms_vs_ref_by_cycles_shift": {str(s): round(float(np.sqrt(((T - r) ** 2).mean())), 5)
                                                 for s, r in ref.items()},
                  "seconds": info["seconds"], "wall_seconds": info["wall_seconds"]})
    # Raw offset per axis: x and y from the view along z, z from the view along x.
    raw = [results[("raw", "z")][0], results[("raw", "z")][1], results[("raw", "x")][2]]
    cor = [results[("corrected", "z")][0], results[("corrected", "z")][1], results[("corrected", "x")][2]]
    emit({"case": "voxel-offset", "cycles_raw_offset_voxels_xyz": [round(float(v), 3) for v in raw],
          "after_correction_voxels_xyz": [round(float(v), 3) for v in cor]})


def case_single_scatter(root, blender):
    vs, origin, ext, n = 10.0, (-80.0, -80.0, -80.0), 2e-5, 16
    rho = np.ones((n, n, n))
    light, intensity = np.array([0.0, 0.0, 200.0]), 1.0e6
    flash = (0.5, 1.0, 2.0)
    medium = {"file": "cube.vdb", "grid": "density", "extinction": ext, "albedo": 1.0, "g": 0.0,
              "voxel_size": vs, "origin": list(origin), "dims": [n, n, n]}
    cam = {"position": [0.0, -1000.0, 0.0], "target": [0.0, 0.0, 0.0], "up": [0, 0, 1],
           "vertical_fov_deg": 12.0}
    fr = frame(cam, medium=medium, lights=[(light, intensity)], flash=flash)

    # Analytic single scattering, integrated along each camera ray through the trilinear cube
    # (edges ramp over +-half a voxel around +-80 m); the light's path is inside the cube for
    # a straight chord through [-80, 80]^3 (the ramps integrate to the sharp box's optical depth).
    sub, steps = 2, 400
    pos, d, _, _ = camera_rays(cam, sub)
    lo, hi = np.asarray(origin) - vs, np.asarray(origin) + (n + 1) * vs
    tmin, tmax = box_chord(pos, d, lo, hi)
    length = np.maximum(tmax - tmin, 0.0)
    u = (np.arange(steps) + 0.5) / steps
    L = np.zeros(d.shape[:-1])
    for r in range(H):
        t = tmin[r][..., None] + length[r][..., None] * u
        p = pos + d[r][:, :, None, :] * t[..., None]                      # (W, sub2, steps, 3)
        dens = trilinear(rho, p, origin, vs)
        tau_cam = ext * np.cumsum(dens, axis=-1) * (length[r][..., None] / steps)
        to_light = light - p
        r2 = (to_light ** 2).sum(-1)
        dl = to_light / np.sqrt(r2)[..., None]
        t0, t1 = box_chord(p, dl, np.asarray(origin), np.asarray(origin) + n * vs)
        tau_light = ext * np.clip(np.minimum(t1, np.sqrt(r2)) - t0, 0.0, None)
        integrand = ext * dens * np.exp(-tau_cam - tau_light) * intensity / (4.0 * math.pi * r2)
        L[r] = integrand.sum(-1) * length[r] / steps
    L = L.mean(-1)
    inside = L > 0.2 * L.max()

    # "scaled": the script as it is (density scale K, see blender_scene.density_scale);
    # "unscaled" (K = 1): shows Cycles' 1e-5 /m cutoff eating the thin medium's fringe.
    for mode, env in (("scaled", None), ("unscaled", {"FULGUR_BLENDER_DENSITY_SCALE": "1"})):
        img, info = render(root, "single_scatter_" + mode, fr, rho, samples=256, env=env, blender=blender)
        rec = {"case": "single-scatter", "mode": mode, "tau_max": round(ext * 160 * math.sqrt(3), 4),
               "channels": {}, "seconds": info["seconds"], "wall_seconds": info["wall_seconds"]}
        for c, name in enumerate("RGB"):
            meas = float(img[:, :, c][inside].mean())
            ana = float(flash[c] * L[inside].mean())
            rec["channels"][name] = {"measured_mean": round(meas, 7), "analytic_mean": round(ana, 7),
                                     "ratio": round(meas / ana, 4)}
        rel = img[:, :, 1][inside] / L[inside] - 1.0
        rec["per_pixel_rel_err_G"] = {"mean": round(float(rel.mean()), 4),
                                      "rms": round(float(np.sqrt((rel ** 2).mean())), 4)}
        rec["image_sum_ratio_G"] = round(float(img[:, :, 1].sum() / L.sum()), 4)
        emit(rec)


def sky_radiance(d, zen, hor):
    f = np.sqrt(np.clip(d[..., 2], 0.0, 1.0))[..., None]
    return np.asarray(hor) + f * (np.asarray(zen) - np.asarray(hor))


def case_sky(root, blender):
    zen, hor = [2.0, 1.0, 0.5], [0.1, 0.2, 0.3]
    sky = {"zenith_rgb": zen, "horizon_rgb": hor, "lights_cloud": True}
    views = {
        "up": {"position": [0, 0, 0], "target": [0, 0, 10], "up": [0, 1, 0], "vertical_fov_deg": 60.0},
        "horizon": {"position": [0, 0, 0], "target": [10, 0, 0], "up": [0, 0, 1], "vertical_fov_deg": 40.0},
    }
    for name, cam in views.items():
        img, info = render(root, "sky_" + name, frame(cam, sky=sky), samples=64, blender=blender)
        _, d, _, _ = camera_rays(cam, 8)
        ref = sky_radiance(d, zen, hor).mean(2)
        mid = slice(H // 2 - 1, H // 2 + 1)
        err = img[:, :, :3] / ref - 1.0
        emit({"case": "sky", "view": name,
              "centre_measured": [round(float(v), 5) for v in img[mid, mid, :3].mean((0, 1))],
              "centre_analytic": [round(float(v), 5) for v in ref[mid, mid].mean((0, 1))],
              "top_row_measured_G": round(float(img[0, :, 1].mean()), 5),
              "top_row_analytic_G": round(float(ref[0, :, 1].mean()), 5),
              "bottom_row_measured_G": round(float(img[-1, :, 1].mean()), 5),
              "bottom_row_analytic_G": round(float(ref[-1, :, 1].mean()), 5),
              "per_pixel_rel_err": {"mean": round(float(err.mean()), 5), "max_abs": round(float(np.abs(err).max()), 5)},
              "alpha_min": round(float(img[:, :, 3].min()), 5),
              "seconds": info["seconds"], "wall_seconds": info["wall_seconds"]})


def case_sun_ground(root, blender):
    a, E = 0.5, np.array([2.0, 1.0, 0.5])
    theta = math.radians(60.0)
    sun = {"direction": [math.sin(theta), 0.0, -math.cos(theta)], "irradiance_rgb": list(E)}
    zen, hor = np.array([0.4, 0.3, 0.2]), np.array([0.1, 0.2, 0.3])
    cam = {"position": [0, 0, 100], "target": [0, 0, 0], "up": [0, 1, 0], "vertical_fov_deg": 30.0}
    for lit in (False, True):
        sky = {"zenith_rgb": list(zen), "horizon_rgb": list(hor), "lights_cloud": lit}
        fr = frame(cam, sun=sun, sky=sky, ground={"height": 0.0, "albedo": a})
        img, info = render(root, "sun_ground_%s" % ("skylit" if lit else "sunonly"), fr,
                           samples=64, blender=blender)
        # cosine-weighted sky: 2 pi int_0^1 (h + (z - h) sqrt(mu)) mu dmu = pi (h + 0.8 (z - h))
        ana = a * E * math.cos(theta) / math.pi + (a * (hor + 0.8 * (zen - hor)) if lit else 0.0)
        meas = img[:, :, :3].mean((0, 1))
        emit({"case": "sun-ground", "sky_lights_ground": lit,
              "measured": [round(float(v), 5) for v in meas], "analytic": [round(float(v), 5) for v in ana],
              "ratio": [round(float(m / x), 4) for m, x in zip(meas, ana)],
              "seconds": info["seconds"], "wall_seconds": info["wall_seconds"]})


def case_furnace(root, blender):
    """A white furnace: a conservative medium (albedo 1, g 0.85, optical depth ~3 across) in a
    uniform sky of radiance 1 must look exactly 1 everywhere (radiance is 1 in equilibrium), which
    needs every scattering order (volume bounces, no clamping). With lights_cloud false the sky
    lights nothing and a pixel is the sky seen through the medium: exp(-tau)."""
    vs, origin, ext, n = 10.0, (-80.0, -80.0, -80.0), 0.02, 16
    rho = np.ones((n, n, n))
    medium = {"file": "cube.vdb", "grid": "density", "extinction": ext, "albedo": 1.0, "g": 0.85,
              "voxel_size": vs, "origin": list(origin), "dims": [n, n, n]}
    cam = {"position": [0.0, -1000.0, 0.0], "target": [0.0, 0.0, 0.0], "up": [0, 0, 1],
           "vertical_fov_deg": 12.0}
    for lit in (True, False):
        sky = {"zenith_rgb": [1, 1, 1], "horizon_rgb": [1, 1, 1], "lights_cloud": lit}
        # Unlit, a sample is 1 (the ray got through) or 0 (it scattered, and the sky is dark to
        # scattered rays): a binomial estimate of T, hence more samples.
        img, info = render(root, "furnace_%s" % ("lit" if lit else "unlit"), frame(cam, medium=medium, sky=sky),
                           rho, samples=64 if lit else 1024, blender=blender)
        G = img[:, :, 1]
        if lit:
            ref = np.ones_like(G)
        else:
            ref = transmittance_image(cam, rho, origin, vs, ext, 0.0)
        inside = transmittance_image(cam, rho, origin, vs, ext, 0.0) < 0.5
        emit({"case": "furnace", "sky_lights_cloud": lit,
              "through_cube_measured_mean": round(float(G[inside].mean()), 5),
              "through_cube_analytic_mean": round(float(ref[inside].mean()), 5),
              "ratio": round(float(G[inside].mean() / ref[inside].mean()), 4),
              "whole_image_ratio": round(float(G.mean() / ref.mean()), 4),
              "seconds": info["seconds"], "wall_seconds": info["wall_seconds"]})


def case_errors(root, blender):
    """A bad frame.json must end Blender with status 1 and a message naming the file and field."""
    cam = {"position": [0, 0, 0], "target": [0, 0, 10], "up": [0, 1, 0], "vertical_fov_deg": 30.0}
    good = frame(cam, medium={"file": "none.vdb", "grid": "density", "extinction": 0.05, "albedo": 0.99,
                              "g": 0.85, "voxel_size": 10.0, "origin": [0, 0, 0], "dims": [4, 4, 4]})
    bad_cases = {
        "missing-extinction": ("medium.extinction", lambda f: f["medium"].pop("extinction")),
        "missing-vdb": ("medium.file", lambda f: None),
        "bad-fov": ("camera.vertical_fov_deg", lambda f: f["camera"].update(vertical_fov_deg="wide")),
        "no-frame": ("frame.json", None),
    }
    for name, (field, mutate) in bad_cases.items():
        d = os.path.join(root, "error_" + name)
        os.makedirs(d, exist_ok=True)
        if mutate is not None:
            f = json.loads(json.dumps(good))
            mutate(f)
            with open(os.path.join(d, "frame.json"), "w") as fh:
                json.dump(f, fh)
        cmd = [blender, "-b", "--factory-startup", "--python", SCENE_SCRIPT, "--", d,
               "--out", os.path.join(root, "error.exr")]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        msg = [l for l in p.stderr.splitlines() if "blender_scene.py: error:" in l]
        emit({"case": "error", "what": name, "exit_status": p.returncode,
              "names_field": bool(msg) and field in msg[0] and "frame.json" in msg[0],
              "message": msg[0] if msg else p.stderr[-300:]})


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--keep", help="write the cases here and keep them (default: a temporary directory)")
    ap.add_argument("--blender", default="blender")
    ap.add_argument("--cases", default="absorption,single-scatter,sky,sun-ground,furnace,errors")
    args = ap.parse_args()
    root = os.path.abspath(args.keep) if args.keep else tempfile.mkdtemp(prefix="fulgur-blender-cal-")
    os.makedirs(root, exist_ok=True)
    cases = {"absorption": case_absorption, "single-scatter": case_single_scatter,
             "sky": case_sky, "sun-ground": case_sun_ground, "furnace": case_furnace,
             "errors": case_errors}
    try:
        for name in args.cases.split(","):
            cases[name](root, args.blender)
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
