#!/usr/bin/python3
"""Fulgur's frame against Cycles' render of the same frame (docs/blender.md).

usage:
  scripts/compare_cycles.py run SCENE.json OUT_DIR --seed S --time [+]T --size WxH
        [--quality PRESET] [--strike-grid N] [--strike-toward-camera] [--static-toward-camera]
        [--samples N] [--cycles-seeds A,B] [--fulgur-shot EXE] [--blender EXE]
        [--light-radius M] [--max-light-loss F] [--single-scattering]
  scripts/compare_cycles.py compare FULGUR.exr CYCLES_A.exr CYCLES_B.exr [--near-px R] [--picture P.png]
        [--picture-block N] [--frame FRAME.json]
  scripts/compare_cycles.py rain SCENE.json OUT_DIR (the options of run)
  scripts/compare_cycles.py channel SCENE.json OUT_DIR (the options of run)

`run` renders the frame with fulgur-shot (--exr with its passes, --blender DIR, one ray-march ray
per pixel), builds and renders the Blender scene twice with Cycles (two seeds), and compares;
`compare` only compares; `--single-scattering` renders the light scattered once alone on both
sides (fulgur-shot --off multiple, exported from a second run with every order; Cycles with no
volume bounce). Both print one JSON line and write OUT_DIR/compare.png (Fulgur | Cycles
| |difference|, each tone mapped alike) when run. `rain` runs the scene (OUT_DIR/wet) and a copy of
it without its "rain" (OUT_DIR/dry; the copies are written into OUT_DIR, so the scene's files must be
found from there, as a generated cloud is), and compares the change the rain makes to its pixels:
the `rain_*` figures below. `channel` renders the channel the camera sees alone (Fulgur's channel
pass; Cycles' `blender_scene.py --channel alone`: the channel's tubes through the media, nothing
lit) and compares them: the `channel_*` figures below.

What is compared: Fulgur's lightning + static + background passes (the cloud lit by the flash's
S and by the sun or moon and sky, over the sky and the ground it transmits) against Cycles'
image, which has the same lights, medium, sky and ground. Left out on Fulgur's side: the
channel's core and its glow in the air (Cycles gets the channel as point lights, which the
camera does not see, and has no air), and the eye's glare (not radiance). No factor is fitted:
both images are radiance in W m^-2 sr^-1.

Regions (Fulgur's transmittance T of each pixel's ray, and its channel pass):
  cloud        T < 0.98: the ray meets cloud
  near         cloud pixels within --near-px of a pixel the channel's core covers
  rest         the other cloud pixels
  background   T >= 0.98: sky and ground seen past at most 2% extinction
  ground       (with the exported frame.json: `run`, `rain`, `compare --frame`) background pixels
               whose ray meets the ground within Fulgur's haze 0.5 (~28 km); for frames exported
               without the haze (no ground.haze_m: Cycles drew none) `ground_dehazed_*` compares
               them with Fulgur's haze taken out
The rain (`rain`): over the pixels whose ray meets rain and no cloud (Fulgur's T < 0.98 with the
rain, > 0.999 without), each renderer's wet pixel less its dry pixel times Fulgur's T (the rain's
own light, less its shadow on what lies behind it), Fulgur against Cycles' (its dry frame the mean
of its two seeds).
With a drawn channel, `rain_channel_0_10_px_*`, `rain_channel_10_30_px_*` and
`rain_channel_30_up_px_*` give the pixels, ratio of totals and Cycles' total noise of the same
by the rain pixel's distance on screen from the channel's nearest pixel (Chebyshev): near it
the channel's own light dominates the rain, farther the light scattered more than once.

The channel (`channel`): Fulgur draws the core at least 1.5 pixels wide, dimmed to keep its flux,
where Cycles draws the channel's physical width, so only sums over areas wider than the core
compare: `channel_ratio_of_totals` (the whole image) and `channel_blocks_*` (--block N blocks
that hold some of either image's channel).

Per region: relative L2 (all three colours: sqrt(sum (f - c)^2 / sum c^2)) and the ratio of
totals sum f / sum c. Cycles' noise: its image is the mean of the two seeds, whose own relative
L2 error is |A - B| / 2 over |mean| (two independent estimates: the difference has twice the
variance of one, the mean half); `*_rel_l2_noise_removed` subtracts it in quadrature and
`*_rel_l2_noise_removed_upper2sigma` bounds it from above at two standard errors of that
subtraction (what "within Cycles' noise" can claim).
"""

import argparse
import json
import math
import pathlib
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio

ROOT = pathlib.Path(__file__).resolve().parent.parent


def read_channels(path):
    """Every channel of an EXR by name, float64, rows top to bottom."""
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise SystemExit(f"{path}: cannot open: {oiio.geterror()}")
    spec = inp.spec()
    px = inp.read_image(oiio.FLOAT)
    inp.close()
    if px is None:
        raise SystemExit(f"{path}: cannot read the pixels")
    px = np.asarray(px, dtype=np.float64).reshape(spec.height, spec.width, spec.nchannels)
    return {name: px[:, :, k] for k, name in enumerate(spec.channelnames)}


def rgb(ch, layer=""):
    p = layer + "." if layer else ""
    return np.stack([ch[p + c] for c in "RGB"], axis=-1)


def dilate(mask, r):
    """Pixels within r (Chebyshev) of a true pixel."""
    out = mask.copy()
    h, w = mask.shape
    # Offsets past the image's size reach no pixel (and would turn the slices' ends negative).
    ry, rx = min(r, h - 1), min(r, w - 1)
    for dy in range(-ry, ry + 1):
        for dx in range(-rx, rx + 1):
            ys, yd = slice(max(0, dy), h + min(0, dy)), slice(max(0, -dy), h + min(0, -dy))
            xs, xd = slice(max(0, dx), w + min(0, dx)), slice(max(0, -dx), w + min(0, -dx))
            out[yd, xd] |= mask[ys, xs]
    return out


def rings(core, bands):
    """For each band (lo, hi) of `bands`: the pixels whose Chebyshev distance from a pixel of `core`
    is in [lo, hi) (hi None: every pixel farther), the bands taken in order of distance."""
    inner = np.zeros_like(core)
    for lo, hi in bands:
        outer = dilate(core, hi - 1) if hi is not None else np.ones_like(core)
        yield lo, hi, outer & ~inner
        inner = outer


def block_mean(x, n):
    """x (H, W, ...) averaged over n x n blocks (the last partial row and column dropped)."""
    h, w = (x.shape[0] // n) * n, (x.shape[1] // n) * n
    x = x[:h, :w]
    return x.reshape(h // n, n, w // n, n, *x.shape[2:]).mean(axis=(1, 3))


def region_figures(f, c, a, b, mask):
    if not mask.any():
        return {"pixels": 0}
    fm, cm, am, bm = f[mask], c[mask], a[mask], b[mask]
    c2 = float(np.sum(cm * cm))
    # Per pixel (summed over the colours): the squared error and Cycles' noise, (a - b)^2 / 4.
    # Their difference is an unbiased estimate of (f - mean)^2 whatever Cycles' noise
    # distribution (c's variance is half a seed's, ((a - b) / 2)^2's mean the same); its spread
    # over the region gives the standard error of its sum, pixels taken as independent, and so a
    # two-sigma upper bound on the error without noise.
    e2 = ((fm - cm) ** 2).reshape(fm.shape[0], -1).sum(axis=1)
    n2 = (((am - bm) / 2) ** 2).reshape(fm.shape[0], -1).sum(axis=1)
    err = math.sqrt(float(np.sum(e2)) / c2) if c2 > 0 else float("nan")
    noise = math.sqrt(float(np.sum(n2)) / c2) if c2 > 0 else float("nan")
    t = e2 - n2
    se = math.sqrt(float(np.sum((t - t.mean()) ** 2))) if t.size > 1 else float("inf")
    upper = math.sqrt(max(0.0, float(np.sum(t)) + 2.0 * se) / c2) if c2 > 0 else float("nan")
    return {
        "pixels": int(mask.sum()),
        "rel_l2": err,
        "cycles_noise_rel_l2": noise,
        "rel_l2_noise_removed": math.sqrt(max(0.0, err * err - noise * noise)),
        "rel_l2_noise_removed_upper2sigma": upper,
        "ratio_of_totals": float(np.sum(fm)) / float(np.sum(cm)) if np.sum(cm) > 0 else float("nan"),
        # The mean's relative noise in the total, from the two seeds' totals (|A - B| / 2 over
        # the mean: a one-sample estimate of it).
        "cycles_total_noise": abs(float(np.sum(am) - np.sum(bm))) / float(np.sum(am) + np.sum(bm))
        if np.sum(cm) > 0 else float("nan"),
    }


# The haze Fulgur lays over its ground (shaders/background.glsl, ground_haze and haze_colour): the
# ground's radiance mixed toward the sky's horizon radiance (none with the sky off) by
# 1 - exp(-t / haze_m), t the ray's distance to the ground. Frames exported before frame.json
# carried haze_m rendered in Blender without it; for them, the distance it had then.
HAZE_DISTANCE_M = 40000.0


def pixel_rays(fulgur_exr, width, height):
    """The camera's position and each pixel centre's unit ray from the EXR's header."""
    inp = oiio.ImageInput.open(str(fulgur_exr))
    if inp is None:
        raise SystemExit(f"{fulgur_exr}: cannot open: {oiio.geterror()}")
    spec = inp.spec()
    inp.close()
    pos = np.array(spec.getattribute("cameraPosition"), dtype=np.float64)
    target = np.array(spec.getattribute("cameraTarget"), dtype=np.float64)
    up = np.array(spec.getattribute("cameraUp"), dtype=np.float64)
    tan_half = math.tan(math.radians(spec.getattribute("cameraVerticalFovDeg")) / 2)
    fwd = (target - pos) / np.linalg.norm(target - pos)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    x = ((np.arange(width) + 0.5) / width * 2 - 1) * tan_half * width / height
    y = (1 - (np.arange(height) + 0.5) / height * 2) * tan_half
    d = fwd + x[None, :, None] * right + y[:, None, None] * up
    return pos, d / np.linalg.norm(d, axis=-1, keepdims=True)


def ground_figures(fulgur_exr, frame_json, f, c, a, b, t):
    """The ground seen past the cloud (T >= 0.98, rays down) where Fulgur's haze h is at most 0.5
    (within ~28 km), as drawn (`ground_*`), and for a frame whose Blender scene has no haze (no
    ground.haze_m) also with Fulgur's haze taken out (f less T h H, over 1 - h: `ground_dehazed_*`)."""
    frame = json.loads(pathlib.Path(frame_json).read_text())
    pos, d = pixel_rays(fulgur_exr, f.shape[1], f.shape[0])
    height = frame["ground"]["height"]
    down = d[..., 2] < 0
    dist = np.where(down, (height - pos[2]) / np.where(down, d[..., 2], -1.0), np.inf)
    hazed_in_blender = "haze_m" in frame["ground"]
    h = 1 - np.exp(-dist / frame["ground"].get("haze_m", HAZE_DISTANCE_M))
    ground = down & (t >= 0.98) & (h <= 0.5)
    out = {f"ground_{k}": v for k, v in region_figures(f, c, a, b, ground).items()}
    if not hazed_in_blender:
        sky = frame.get("sky") or {}
        horizon = np.array(sky["horizon_rgb"]) if sky.get("visible") else np.zeros(3)
        dehazed = (f - (t * h)[..., None] * horizon) / (1 - np.minimum(h, 0.5))[..., None]
        out.update({f"ground_dehazed_{k}": v for k, v in region_figures(dehazed, c, a, b, ground).items()})
    return out


def compare(fulgur_exr, cycles_a, cycles_b, near_px=None, picture=None, block=8, picture_block=1, frame_json=None):
    fc = read_channels(fulgur_exr)
    for need in ("lightning.R", "static.R", "background.R", "channel.R", "T.Y"):
        if need not in fc:
            raise SystemExit(f"{fulgur_exr}: no channel {need} (write it with fulgur-shot --exr-passes)")
    f = rgb(fc, "lightning") + rgb(fc, "static") + rgb(fc, "background")
    a, b = rgb(read_channels(cycles_a)), rgb(read_channels(cycles_b))
    if a.shape != f.shape or b.shape != f.shape:
        raise SystemExit(f"image sizes differ: Fulgur {f.shape[:2]}, Cycles {a.shape[:2]} and {b.shape[:2]}")
    c = (a + b) / 2
    t = fc["T.Y"]
    h = f.shape[0]
    r = near_px if near_px is not None else max(1, round(0.05 * h))
    cloud = t < 0.98
    core = rgb(fc, "channel").sum(axis=-1) > 0
    near = cloud & dilate(core, r)
    out = {"name": "compare-cycles", "width": f.shape[1], "height": h, "near_px": r}
    for name, m in (("cloud", cloud), ("near", near), ("rest", cloud & ~near), ("background", ~cloud)):
        for k, v in region_figures(f, c, a, b, m).items():
            out[f"{name}_{k}"] = v
    # The cloud at a coarser scale: n x n blocks at least half cloud (per-pixel noise averages
    # out n^2-fold in variance; what is left is structure larger than a block).
    n = block
    blocks_cloud = block_mean(cloud.astype(np.float64), n) >= 0.5
    fb, cb, ab, bb = (block_mean(x, n) for x in (f, c, a, b))
    for k, v in region_figures(fb, cb, ab, bb, blocks_cloud).items():
        out[f"cloud_blocks_{k}"] = v
    out["block_px"] = n
    if frame_json:
        out.update(ground_figures(fulgur_exr, frame_json, f, c, a, b, t))
    if picture:
        if picture_block > 1:  # the scale the block figures measure: each block's mean, shown as a block
            up = lambda x: np.repeat(np.repeat(block_mean(x, picture_block), picture_block, 0), picture_block, 1)
            write_picture(picture, up(f), up(c))
        else:
            write_picture(picture, f, c)
    return out


def compare_channel(fulgur_exr, cycles_a, cycles_b, block):
    """Fulgur's channel pass against Cycles' channel alone (module docstring, `channel`)."""
    fc = read_channels(fulgur_exr)
    if "channel.R" not in fc:
        raise SystemExit(f"{fulgur_exr}: no channel channel.R (write it with fulgur-shot --exr-passes)")
    f = rgb(fc, "channel")
    a, b = rgb(read_channels(cycles_a)), rgb(read_channels(cycles_b))
    if a.shape != f.shape or b.shape != f.shape:
        raise SystemExit(f"image sizes differ: Fulgur {f.shape[:2]}, Cycles {a.shape[:2]} and {b.shape[:2]}")
    c = (a + b) / 2
    out = {"name": "compare-cycles-channel", "width": f.shape[1], "height": f.shape[0], "block_px": block}
    for k, v in region_figures(f, c, a, b, np.ones(f.shape[:2], dtype=bool)).items():
        if "ratio" in k or "total" in k:
            out[f"channel_{k}"] = v
    fb, cb, ab, bb = (block_mean(x, block) for x in (f, c, a, b))
    lit = (fb.sum(axis=-1) > 0) | (cb.sum(axis=-1) > 0)
    for k, v in region_figures(fb, cb, ab, bb, lit).items():
        out[f"channel_blocks_{k}"] = v
    return out


def write_picture(path, f, c):
    """Fulgur | Cycles | |difference|, one exposure for all three (the cloud's 99th percentile
    of Cycles' luminance at 0.8 of white), a plain Reinhard curve and sRGB."""
    lum = lambda x: 0.2126 * x[..., 0] + 0.7152 * x[..., 1] + 0.0722 * x[..., 2]
    k = 0.8 / max(np.percentile(lum(c), 99), 1e-30)
    tone = lambda x: np.clip(x * k / (1 + x * k), 0, 1) ** (1 / 2.2)
    img = np.concatenate([tone(f), tone(c), tone(np.abs(f - c))], axis=1)
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.UINT8)
    out.open(str(path), spec)
    out.write_image(np.ascontiguousarray((img * 255 + 0.5).astype(np.uint8)))
    out.close()


# The rain's pixels by their distance on screen (Chebyshev, pixels) from the nearest pixel of
# the drawn channel: [lo, hi), the last without end.
RAIN_CHANNEL_BANDS = [(0, 10), (10, 30), (30, None)]


class RainFrames:
    """A `run` of the scene (`wet`) and of it without rain (`dry`): the pixels that see rain and
    no cloud (`mask`: Fulgur's T < 0.98 wet, > 0.999 dry), the change the rain makes to Fulgur's
    passes (`fulgur_change`: wet less dry times the rain's T), Cycles' change for each seed (`a`,
    `b`; its dry frame the seeds' mean) and the drawn channel's pixels (`core`; None without a
    channel pass)."""

    def __init__(self, wet, dry, seeds):
        self.fw, self.fd = read_channels(wet / "fulgur.exr"), read_channels(dry / "fulgur.exr")
        self.t = self.fw["T.Y"][..., None]
        self.mask = (self.fw["T.Y"] < 0.98) & (self.fd["T.Y"] > 0.999)
        cycles = lambda d, s: rgb(read_channels(d / f"cycles_{s}.exr"))  # noqa: E731
        dry_c = (cycles(dry, seeds[0]) + cycles(dry, seeds[1])) / 2
        self.a, self.b = cycles(wet, seeds[0]) - dry_c * self.t, cycles(wet, seeds[1]) - dry_c * self.t
        self.core = rgb(self.fw, "channel").sum(axis=-1) > 0 if "channel.R" in self.fw else None

    def fulgur_change(self, layers=("lightning", "static", "background")):
        return sum(rgb(self.fw, p) - rgb(self.fd, p) * self.t for p in layers)


def rain_change(wet, dry, seeds):
    """The rain's figures (module docstring) from a `run` of the scene (`wet`) and of it without rain."""
    r = RainFrames(wet, dry, seeds)
    mask, a, b, core = r.mask, r.a, r.b, r.core
    f = r.fulgur_change()
    out = {"rain_" + k: v for k, v in region_figures(f, (a + b) / 2, a, b, mask).items()}
    # By distance on screen from the nearest pixel of the drawn channel (Fulgur's channel pass):
    # near it the channel's own light dominates the rain, farther the light scattered more than once.
    if core is not None and core.any():
        for lo, hi, ring in rings(core, RAIN_CHANNEL_BANDS):
            name = "rain_channel_%d_%s_px_" % (lo, "up" if hi is None else "%d" % hi)
            for k, v in region_figures(f, (a + b) / 2, a, b, mask & ring).items():
                if k in ("pixels", "ratio_of_totals", "cycles_total_noise"):
                    out[name + k] = v
    return out


def rain(args):
    out = pathlib.Path(args.out_dir)
    scene = json.loads(pathlib.Path(args.scene).read_text())
    if not scene.get("rain"):
        raise SystemExit(f"{args.scene}: the scene has no rain")
    res = {}
    for name in ("wet", "dry"):
        d = out / name
        d.mkdir(parents=True, exist_ok=True)
        copy = {k: v for k, v in scene.items() if not (name == "dry" and k == "rain")}
        (d / "scene.json").write_text(json.dumps(copy, indent=1))
        one = argparse.Namespace(**vars(args))
        one.scene, one.out_dir = str(d / "scene.json"), str(d / "out")
        r = run(one)
        res.update({f"{name}_{k}": v for k, v in r.items() if k.startswith(("cloud_", "background_", "ground_"))})
        res[f"{name}_cycles_seconds"] = r["cycles_seconds"]
    res.update(rain_change(out / "wet/out", out / "dry/out", [int(s) for s in args.cycles_seeds.split(",")]))
    res.update({"scene": args.scene, "camera": args.camera, "samples": args.samples})
    return res


def run(args):
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    frame = [args.fulgur_shot, args.scene, "--seed", str(args.seed), "--time", args.time, "--size", args.size,
             "--internal-scale", "1"]
    if args.camera:
        frame += ["--camera", args.camera]
    if args.quality:
        frame += ["--quality", args.quality]
    if args.strike_grid:
        frame += ["--strike-grid", str(args.strike_grid)]
    if args.static_toward_camera:
        frame += ["--static-toward-camera"]
    if args.strike_toward_camera:
        frame += ["--strike-toward-camera"]
    images = ["-o", str(out / "fulgur.png"), "--exr", str(out / "fulgur.exr"), "--exr-passes"]
    export = ["--blender", str(out / "blender")]
    t0 = time.monotonic()
    if args.single_scattering:
        # fulgur-shot exports the whole light (--blender refuses a frame without some orders),
        # so the export and the single-scattering frame are two runs.
        subprocess.run(frame + ["-o", str(out / "export.png")] + export, check=True, stdout=subprocess.DEVNULL)
        shot = frame + images + ["--off", "multiple"]
    else:
        shot = frame + images + export
    subprocess.run(shot, check=True, stdout=subprocess.DEVNULL)
    fulgur_s = time.monotonic() - t0
    seeds = [int(s) for s in args.cycles_seeds.split(",")]
    if len(seeds) != 2:
        raise SystemExit("--cycles-seeds takes two seeds")
    cycles_s, lights = [], None
    for s in seeds:
        t0 = time.monotonic()
        done = subprocess.run([args.blender, "-b", "--factory-startup", "--python",
                               str(ROOT / "scripts/blender_scene.py"), "--", str(out / "blender"),
                               "--out", str(out / f"cycles_{s}.exr"),
                               "--samples", str(args.samples), "--seed", str(s)]
                              + (["--light-radius", args.light_radius] if args.light_radius else [])
                              + (["--max-light-loss", args.max_light_loss] if args.max_light_loss else [])
                              + ["--channel", getattr(args, "channel_mode", "hidden")]
                              + (["--single-scattering"] if args.single_scattering else []),
                              check=True, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        cycles_s.append(time.monotonic() - t0)
        line = [l for l in done.stdout.splitlines() if l.startswith('{"name":"blender-scene"')]
        lights = json.loads(line[-1]) if line else lights
    if getattr(args, "channel_mode", "hidden") == "alone":
        r = compare_channel(out / "fulgur.exr", out / f"cycles_{seeds[0]}.exr", out / f"cycles_{seeds[1]}.exr",
                            args.block)
    else:
        r = compare(out / "fulgur.exr", out / f"cycles_{seeds[0]}.exr", out / f"cycles_{seeds[1]}.exr",
                    args.near_px, out / "compare.png", args.block, frame_json=out / "blender" / "frame.json")
    r.update({"scene": args.scene, "seed": args.seed, "time": args.time, "quality": args.quality or "scene's",
              "strike_grid": args.strike_grid, "strike_toward_camera": args.strike_toward_camera,
              "static_toward_camera": args.static_toward_camera,
              "samples": args.samples, "fulgur_seconds": fulgur_s, "cycles_seconds": cycles_s,
              "cycles_light_radius": lights and lights.get("light_radius"),
              "cycles_light_loss": lights and lights.get("light_loss")})
    return r


def add_run_arguments(r):
    """The arguments of `run` (and of `rain`, which runs twice)."""
    r.add_argument("scene")
    r.add_argument("out_dir")
    r.add_argument("--camera", help="passed to fulgur-shot (the exported frame carries it to Blender)")
    r.add_argument("--seed", type=int, required=True)
    r.add_argument("--time", required=True)
    r.add_argument("--size", required=True)
    r.add_argument("--quality")
    r.add_argument("--strike-grid", type=int, help="passed to fulgur-shot: keep the solved strike's S on the "
                   "lighting grid refined by this factor")
    r.add_argument("--strike-toward-camera", action="store_true", help="passed to fulgur-shot: the solved "
                   "strike's S tallied toward the camera")
    r.add_argument("--static-toward-camera", action="store_true", help="passed to fulgur-shot: the sun's, moon's "
                   "and sky's light solved by Monte Carlo toward the camera on the transport grid")
    r.add_argument("--samples", type=int, default=64)
    r.add_argument("--single-scattering", action="store_true", help="light scattered once in the media alone, "
                   "on both sides (fulgur-shot --off multiple; blender_scene.py --single-scattering): "
                   "splits a difference between the orders")
    r.add_argument("--cycles-seeds", default="1,2")
    r.add_argument("--near-px", type=int)
    r.add_argument("--fulgur-shot", default=str(ROOT / "build/release/app/fulgur-shot"))
    r.add_argument("--blender", default="blender")
    r.add_argument("--light-radius", help="passed to blender_scene.py (default: the largest radius whose share "
                   "of the first collisions withheld from the cloud is within --max-light-loss)")
    r.add_argument("--max-light-loss", help="passed to blender_scene.py (default 0.01)")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r, w, h = sub.add_parser("run"), sub.add_parser("rain"), sub.add_parser("channel")
    add_run_arguments(r)
    add_run_arguments(w)
    add_run_arguments(h)
    c = sub.add_parser("compare")
    c.add_argument("fulgur")
    c.add_argument("cycles_a")
    c.add_argument("cycles_b")
    c.add_argument("--near-px", type=int)
    c.add_argument("--picture", help="also write Fulgur | Cycles | |difference| as this PNG")
    c.add_argument("--picture-block", type=int, default=1, help="the picture's pixels averaged over N x N "
                   "blocks (the scale of the block figures, above Cycles' per-pixel noise)")
    c.add_argument("--frame", help="the exported frame.json (fulgur-shot --blender): also the ground's figures, "
                   "as drawn and with Fulgur's haze taken out (ground_*, ground_dehazed_*)")
    for q in (r, w, h, c):
        q.add_argument("--block", type=int, default=8, help="block size (pixels) of the cloud_blocks_* figures")
        q.add_argument("--require", action="append",
                       help="KEY<=VALUE or KEY>=VALUE on a printed figure; exit 1 when one fails (repeatable)")
    args = p.parse_args()
    if args.cmd == "run":
        res = run(args)
    elif args.cmd == "rain":
        res = rain(args)
    elif args.cmd == "channel":
        args.channel_mode = "alone"
        res = run(args)
    else:
        res = compare(args.fulgur, args.cycles_a, args.cycles_b, args.near_px, args.picture, args.block,
                      args.picture_block, args.frame)
    print(json.dumps(res))
    sys.stdout.flush()
    failed = []
    for req in args.require or []:
        for op in ("<=", ">="):
            if op in req:
                key, bound = req.split(op)
                v = res.get(key)
                if v is None:
                    raise SystemExit(f"--require {req}: no figure {key}")
                if not (v <= float(bound) if op == "<=" else v >= float(bound)):
                    failed.append(f"{key} = {v:.4g}, required {op} {bound}")
                break
        else:
            raise SystemExit(f"--require {req}: expected KEY<=VALUE or KEY>=VALUE")
    if failed:
        print("compare_cycles: " + "; ".join(failed), file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
