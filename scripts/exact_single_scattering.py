#!/usr/bin/python3
"""Single scattering of an exported frame computed by brute force: a third opinion beside
Fulgur's image and Cycles' (docs/blender.md, "The content scenes against Cycles").

usage:
  scripts/exact_single_scattering.py DIR OUT.json [--medium pc|trilinear] [--stride N]
        [--step M] [--shadow-samples K] [--window X0,Y0,X1,Y1]
  scripts/exact_single_scattering.py compare DIR OUT_PC.json OUT_TRILINEAR.json FULGUR.exr CYCLES_A.exr CYCLES_B.exr
        [--max-t T]
  scripts/exact_single_scattering.py compare-rain RUN OUT.json

DIR is what `fulgur-shot ... --blender DIR` writes (frame.json, density.vdb). For every N-th pixel
(both axes, from N / 2) the camera ray is sampled every M metres until its optical depth reaches
12, and at each sample the light of every exported point light arrives attenuated along a
straight shadow ray sampled at K points, scattered once by the Henyey-Greenstein phase function:

  L = sum over samples of exp(-tau_camera) albedo sigma_t (sum over lights of I p(cos) exp(-tau_light) / r^2) M

in W m^-2 sr^-1 per unit flash colour. A frame with rain (frame.json's "rain", rain.vdb) has it
as a second medium: its extinction adds to the cloud's on every ray and it scatters its share
with its own albedo and phase function; its part of each pixel is also written apart
("rain_pixels"). `--window` samples only the pixels with X0 <= x < X1, Y0 <= y < Y1. And when
the frame has a sun (or moon), its single
scattering apart: parallel light of the sun's irradiance (green) through a shadow ray to the
medium's box, in W m^-2 sr^-1. The medium is the density grid read either piecewise
constant per voxel (`pc`: what Fulgur's Monte Carlo truth and its solvers transport light
through) or trilinear between voxel centres and zero outside (`trilinear`: what Fulgur's march
and Cycles read). No light bounces off the ground and no light scatters twice: compare it with
`fulgur-shot --off multiple` and Cycles with `blender_scene.py --single-scattering`.

`compare-rain` takes a `compare_cycles.py rain ... --single-scattering` run (RUN: its OUT_DIR)
and OUT.json made over RUN/wet/out/blender: over the sampled pixels that see rain and no cloud,
all of them and by distance on screen from the drawn channel (0-1, 1-2, 2-4, 4-8, 8-16 pixels),
Fulgur's rain light (its lightning pass, wet less dry times the rain's transmittance), its whole
change (with the ground seen through the rain) and Cycles' whole change, each over the exact's
rain light, with Cycles' noise.

`compare` prints the totals over the sampled cloud pixels (Fulgur's transmittance < T, 0.98
unless --max-t says) of the two exact images, Fulgur's lightning pass and the mean of the two
Cycles images (green channel, the exact images times the flash's green), and their ratios; the
same for the sun against Fulgur's static pass (`sun_*`). Cycles' image also holds what is seen
through the cloud (the ground, which the channel or the sun lights): on a frame where that is
not negligible against single scattering, compare opaque pixels only (--max-t 0.02).
"""

import json
import math
import pathlib
import sys

import numpy as np


def read_grid(directory, entry):
    """The dense grid of a frame.json medium entry (its "file", "grid" and "dims")."""
    import pyopenvdb as vdb

    nx, ny, nz = entry["dims"]
    grid = vdb.read(str(pathlib.Path(directory) / entry["file"]), entry["grid"])
    values = np.zeros((nx, ny, nz), np.float32)
    grid.copyToArray(values, ijk=(0, 0, 0))
    return values


def load(directory):
    d = pathlib.Path(directory)
    frame = json.loads((d / "frame.json").read_text())
    if frame["medium"] is None:
        raise SystemExit(f"{d / 'frame.json'}: no medium")
    return frame, read_grid(d, frame["medium"])


def hg(g, cos):
    """Henyey-Greenstein phase function at cos = the light's travel . the way toward the eye."""
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * cos) ** 1.5)


def density_sampler(rho, origin, voxel, medium):
    dims = np.array(rho.shape)

    def pc(p):
        i = np.floor((p - origin) / voxel).astype(np.int64)
        inside = np.all((i >= 0) & (i < dims), axis=-1)
        i = np.clip(i, 0, dims - 1)
        return np.where(inside, rho[i[..., 0], i[..., 1], i[..., 2]], 0.0)

    # Trilinear: a zero border around the grid, so every corner is an index into it (a point
    # beyond the border clips onto zeros) and the fringe half a voxel outside fades to zero.
    padded = np.zeros(tuple(dims + 2), np.float32)
    padded[1:-1, 1:-1, 1:-1] = rho
    flat = padded.ravel()
    sy, sx = dims[2] + 2, (dims[1] + 2) * (dims[2] + 2)
    offsets = [dx * sx + dy * sy + dz for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)]

    def trilinear(p):
        u = (p - origin) / voxel + 0.5  # values at voxel centres; +1 for the border, -0.5
        u = np.clip(u, 0.0, dims + 1 - 1e-9)
        i0 = np.minimum(np.floor(u).astype(np.int64), dims)
        t = u - i0
        base = i0[..., 0] * sx + i0[..., 1] * sy + i0[..., 2]
        tx, ty, tz = t[..., 0], t[..., 1], t[..., 2]
        out = np.zeros(p.shape[:-1])
        k = 0
        for wx in (1.0 - tx, tx):
            for wy in (1.0 - ty, ty):
                wxy = wx * wy
                for wz in (1.0 - tz, tz):
                    out += flat[base + offsets[k]] * (wxy * wz)
                    k += 1
        return out

    return pc if medium == "pc" else trilinear


def load_rain(directory, frame):
    """The frame's rain (frame.json "rain", rain.vdb) as its extinction grid in 1/m, or None."""
    r = frame.get("rain")
    return read_grid(directory, r) * np.float32(r["extinction"]) if r else None


def render(directory, out, medium="pc", stride=4, step=5.0, shadow_samples=256, window=None):
    frame, rho = load(directory)
    m = frame["medium"]
    origin = np.array(m["origin"], float)
    voxel = float(m["voxel_size"])
    kappa, albedo, g = m["extinction"], m["albedo"], m["g"]
    density = density_sampler(rho, origin, voxel, medium)
    # The rain, a second medium on its own grid: its extinction adds to the cloud's, and it
    # scatters its share with its own albedo and phase function.
    rain_grid = load_rain(directory, frame)
    if rain_grid is not None:
        rf = frame["rain"]
        rain_at = density_sampler(rain_grid, np.array(rf["origin"], float), float(rf["voxel_size"]), medium)
        rain_albedo, rain_g = rf["albedo"], rf["g"]
    else:
        rain_at = lambda p: np.zeros(p.shape[:-1])  # noqa: E731
        rain_albedo, rain_g = 0.0, 0.0
    lights = np.array([l["position"] for l in frame["lights"]], float).reshape(-1, 3)
    intensity = np.array([l["intensity"] for l in frame["lights"]], float)
    cam = frame["camera"]
    width, height = frame["image"]["width"], frame["image"]["height"]
    eye = np.array(cam["position"], float)
    forward = np.array(cam["target"], float) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, cam["up"])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tan_half = math.tan(math.radians(cam["vertical_fov_deg"]) / 2.0)
    # Where the medium can be non-zero: the grid, and for the trilinear medium the half voxel
    # beyond its faces where the last values fade to zero.
    fringe = 0.5 * voxel if medium == "trilinear" else 0.0
    lo, hi = origin - fringe, origin + voxel * np.array(rho.shape) + fringe
    along = (np.arange(shadow_samples) + 0.5) / shadow_samples
    sun = frame.get("sun")
    if sun is not None:
        travel = np.array(sun["direction"], float)
        travel /= np.linalg.norm(travel)
        to_sun, sun_green = -travel, float(sun["irradiance_rgb"][1])
    pixels, sun_pixels, rain_pixels = {}, {}, {}
    x0, y0, x1, y1 = window if window else (0, 0, width, height)
    for py in range(y0 + stride // 2, y1, stride):
        for px in range(x0 + stride // 2, x1, stride):
            sx = (2.0 * (px + 0.5) / width - 1.0) * tan_half * width / height
            sy = (1.0 - 2.0 * (py + 0.5) / height) * tan_half
            d = forward + sx * right + sy * up
            d /= np.linalg.norm(d)
            with np.errstate(divide="ignore", invalid="ignore"):
                t0 = np.where(d != 0.0, (lo - eye) / d, -np.inf)
                t1 = np.where(d != 0.0, (hi - eye) / d, np.inf)
            near, far = np.max(np.minimum(t0, t1)), np.min(np.maximum(t0, t1))
            if not near < far:
                continue
            t = np.arange(max(near, 0.0) + 0.5 * step, far, step)
            x = eye + t[:, None] * d
            sigma_c = kappa * density(x)
            sigma_r = rain_at(x)
            sigma = sigma_c + sigma_r
            tau = np.cumsum(sigma) * step - 0.5 * sigma * step  # to each sample's middle
            keep = (tau < 12.0) & (sigma > 0.0)
            if not keep.any():
                continue
            x, sigma, sigma_c, sigma_r, tau = x[keep], sigma[keep], sigma_c[keep], sigma_r[keep], tau[keep]
            v = lights[None, :, :] - x[:, None, :]
            r = np.linalg.norm(v, axis=-1)
            points = x[:, None, None, :] + v[:, :, None, :] * along[None, None, :, None]
            tau_light = (kappa * density(points) + rain_at(points)).sum(-1) * r / shadow_samples
            cos = np.einsum("slk,k->sl", -v / r[..., None], -d)  # light's travel . toward the eye
            unphased = intensity[None, :] * np.exp(-tau_light) / (r * r)
            cloud = (unphased * hg(g, cos)).sum(-1)
            seen = np.exp(-tau) * step
            pixels[f"{px},{py}"] = float((seen * albedo * sigma_c * cloud).sum())
            if rain_grid is not None:
                rain = (unphased * hg(rain_g, cos)).sum(-1)
                rain_pixels[f"{px},{py}"] = float((seen * rain_albedo * sigma_r * rain).sum())
                pixels[f"{px},{py}"] += rain_pixels[f"{px},{py}"]
            if sun is not None:
                # The sun: parallel light of irradiance E (green) from -travel, attenuated from
                # where the shadow ray leaves the medium's box.
                with np.errstate(divide="ignore", invalid="ignore"):
                    exits = np.where(to_sun != 0.0, (np.where(to_sun > 0.0, hi, lo) - x) / to_sun, np.inf)
                t_exit = np.maximum(exits.min(axis=-1), 0.0)
                points = x[:, None, :] + (t_exit[:, None] * along[None, :])[..., None] * to_sun
                tau_sun = (kappa * density(points) + rain_at(points)).sum(-1) * t_exit / shadow_samples
                cos = float(np.dot(travel, -d))
                scattered = albedo * sigma_c * hg(g, cos) + rain_albedo * sigma_r * hg(rain_g, cos)
                sun_pixels[f"{px},{py}"] = float(
                    (np.exp(-tau) * scattered * sun_green * np.exp(-tau_sun)).sum() * step)
    pathlib.Path(out).write_text(json.dumps({"medium": medium, "stride": stride, "step": step,
                                             "shadow_samples": shadow_samples, "pixels": pixels,
                                             "sun_pixels": sun_pixels, "rain_pixels": rain_pixels}))
    print(json.dumps({"medium": medium, "pixels": len(pixels), "total": sum(pixels.values()),
                      "sun_total": sum(sun_pixels.values()), "rain_total": sum(rain_pixels.values())}))


def compare(directory, pc_json, tri_json, fulgur_exr, cycles_a, cycles_b, max_t=0.98):
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from compare_cycles import read_channels

    frame = json.loads((pathlib.Path(directory) / "frame.json").read_text())
    green = frame["flash_colour"][1]  # the exact images are per unit flash colour
    f, a, b = read_channels(fulgur_exr), read_channels(cycles_a), read_channels(cycles_b)
    pc, tri = (json.loads(pathlib.Path(p).read_text()) for p in (pc_json, tri_json))

    def totals(key, scale, layer):
        """Sums over the sampled pixels under max_t: exact pc, exact trilinear, Fulgur's layer, Cycles."""
        rows = []
        for k, value in pc.get(key, {}).items():
            px, py = map(int, k.split(","))
            if f["T.Y"][py, px] < max_t:
                rows.append((scale * value, scale * tri.get(key, {}).get(k, 0.0), f[layer][py, px],
                             0.5 * (a["G"][py, px] + b["G"][py, px])))
        return len(rows), np.array(rows).reshape(-1, 4).sum(axis=0)

    n, flash = totals("pixels", green, "lightning.G")
    if not n:
        raise SystemExit("no sampled pixel sees the cloud")
    out = {"cloud_pixels": n, "max_transmittance": max_t}
    figures(out, "", flash)
    # The sun's single scattering (a frame the sun or moon lights): against Fulgur's static pass.
    _, sun = totals("sun_pixels", 1.0, "static.G")
    if sun[0] > 0.0:
        figures(out, "sun_", sun)
    print(json.dumps(out))


# The rain's pixels by their distance on screen (Chebyshev, pixels) from the drawn channel:
# [lo, hi); 0-1 the channel's own pixels.
RAIN_BANDS = [(0, 1), (1, 2), (2, 4), (4, 8), (8, 16)]


def compare_rain(run_dir, exact_json):
    """The rain's first order from the channel (`rain_pixels` of a run over RUN/wet/out/blender)
    against a `compare_cycles.py rain ... --single-scattering` run's frames in RUN: over the
    sampled pixels that see rain and no cloud, Fulgur's lightning pass change (wet less dry times
    the rain's T: the rain's own light), its whole change (the ground seen through the rain too)
    and Cycles' (its whole change), each over the exact's, by distance from the drawn channel."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from compare_cycles import RainFrames, rings

    wet, dry = pathlib.Path(run_dir) / "wet/out", pathlib.Path(run_dir) / "dry/out"
    frame = json.loads((wet / "blender/frame.json").read_text())
    colour = sum(frame["flash_colour"])  # the exact is per unit flash colour; the sums are over r, g, b
    r = RainFrames(wet, dry, (1, 2))
    mask, core = r.mask, r.core
    rain_light, whole = r.fulgur_change(("lightning",)).sum(-1), r.fulgur_change().sum(-1)
    cycles = [r.a.sum(-1), r.b.sum(-1)]
    exact = np.full(mask.shape, np.nan)
    for k, v in json.loads(pathlib.Path(exact_json).read_text())["rain_pixels"].items():
        px, py = map(int, k.split(","))
        exact[py, px] = v * colour
    sampled = mask & ~np.isnan(exact)
    if core is None:
        raise SystemExit(f"{wet / 'fulgur.exr'}: no channel pass (fulgur-shot --exr-passes)")
    out = {"name": "exact-rain", "run": str(run_dir)}

    def add(name, region):
        e = exact[region].sum()
        if not region.any() or not e > 0.0:
            return
        c = [x[region].sum() for x in cycles]
        out.update({name + "pixels": int(region.sum()), name + "exact": float(e),
                    name + "fulgur_rain_over_exact": float(rain_light[region].sum() / e),
                    name + "fulgur_whole_over_exact": float(whole[region].sum() / e),
                    name + "cycles_over_exact": float((c[0] + c[1]) / 2 / e),
                    name + "cycles_noise": float(abs(c[0] - c[1]) / 2 / e)})

    add("", sampled)
    for lo, hi, ring in rings(core, RAIN_BANDS):
        add("band_%d_%d_px_" % (lo, hi), sampled & ring)
    print(json.dumps(out))


def figures(out, prefix, totals):
    exact_pc, exact_tri, fulgur, cycles = totals
    ratio = lambda x, y: x / y if y > 0.0 else None  # noqa: E731
    out.update({prefix + "exact_pc": exact_pc, prefix + "exact_trilinear": exact_tri, prefix + "fulgur": fulgur,
                prefix + "cycles": cycles, prefix + "fulgur_over_exact_pc": ratio(fulgur, exact_pc),
                prefix + "fulgur_over_exact_trilinear": ratio(fulgur, exact_tri),
                prefix + "cycles_over_exact_pc": ratio(cycles, exact_pc),
                prefix + "cycles_over_exact_trilinear": ratio(cycles, exact_tri),
                prefix + "exact_trilinear_over_pc": ratio(exact_tri, exact_pc)})


def main(argv):
    if argv[:1] == ["compare"] and len(argv) in (7, 9) and (len(argv) == 7 or argv[7] == "--max-t"):
        compare(*argv[1:7], max_t=float(argv[8]) if len(argv) == 9 else 0.98)
        return
    if argv[:1] == ["compare-rain"] and len(argv) == 3:
        compare_rain(argv[1], argv[2])
        return
    if len(argv) < 2 or argv[0] in ("compare", "compare-rain"):
        raise SystemExit(__doc__)
    opts = {"--medium": "pc", "--stride": "4", "--step": "5", "--shadow-samples": "256", "--window": None}
    rest = argv[2:]
    if len(rest) % 2:
        raise SystemExit(__doc__)
    for k, v in zip(rest[::2], rest[1::2]):
        if k not in opts:
            raise SystemExit(f"unknown option {k}\n{__doc__}")
        opts[k] = v
    if opts["--medium"] not in ("pc", "trilinear"):
        raise SystemExit("--medium: pc or trilinear")
    window = None
    if opts["--window"] is not None:
        try:
            window = [int(v) for v in opts["--window"].split(",")]
        except ValueError:
            window = []
        if len(window) != 4 or window[0] >= window[2] or window[1] >= window[3] or min(window) < 0:
            raise SystemExit("--window: X0,Y0,X1,Y1 (pixels, X0 < X1, Y0 < Y1)")
    render(argv[0], argv[1], opts["--medium"], int(opts["--stride"]), float(opts["--step"]),
           int(opts["--shadow-samples"]), window)


if __name__ == "__main__":
    main(sys.argv[1:])
