#!/usr/bin/python3
"""scripts/exact_single_scattering.py compare-rain on frames made to known answers.

A 12 x 8 frame pair (wet, dry) as `compare_cycles.py rain ... --single-scattering` leaves them:
Fulgur's EXR with its T, lightning, static, background and channel passes, two Cycles seeds each,
the wet export's frame.json (its flash colour), and an exact single scattering's `rain_pixels`.
The drawn channel is column 2. Every other pixel sees rain (T 0.5 wet, 1 dry) except one that
sees cloud in the dry frame too and one the exact did not sample: both must be left out. Per
rain pixel the exact's light is v (per unit flash colour, colour (1, 2, 3)); Fulgur's lightning
pass holds k(band) x v x colour / 6 per channel, its static pass 0.05 x the same and its
background T x the dry one (no change), so by distance from the channel its rain light over the
exact is k(band) and its whole change k(band) + 0.05; Cycles' two seeds differ by +-10% of the
exact, so its ratio is 1 and its noise 0.1. The script must print those band by band, with
the pixel counts of its bands, to the frames' float32 rounding (~6e-8 of each stored value;
measured 4e-8 of a figure at worst; bound 1e-6): a band cut one pixel off, a flash colour left
out, the T not applied or a pixel not sampled counted would each move a figure by percents.
(The bands reach past this small frame's edge: compare_cycles.dilate must clip its offsets.)
"""

import json
import pathlib
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

SCRIPT = pathlib.Path(__file__).resolve().parents[2] / "scripts/exact_single_scattering.py"
W, H, CORE_X = 12, 8, 2
COLOUR = (1.0, 2.0, 3.0)
BANDS = [(0, 1), (1, 2), (2, 4), (4, 8), (8, 16)]  # exact_single_scattering.RAIN_BANDS
K = {0: 0.8, 1: 0.9, 2: 1.0, 3: 1.1, 4: 0.7}  # Fulgur's rain light over the exact, per band
CLOUD, UNSAMPLED = (7, 3), (9, 5)  # (x, y): seen through cloud dry; not in the exact's pixels


def band_of(x):
    d = abs(x - CORE_X)  # the channel is a full column: Chebyshev distance is the column's
    for b, (lo, hi) in enumerate(BANDS):
        if lo <= d < hi:
            return b
    raise AssertionError(x)


def write_exr(path, layers):
    names = [n for n in layers]
    px = np.stack([layers[n] for n in names], axis=-1).astype(np.float32)
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(W, H, len(names), oiio.FLOAT)
    spec.channelnames = tuple(names)
    assert out.open(str(path), spec), oiio.geterror()
    assert out.write_image(px), oiio.geterror()
    out.close()


def main():
    v = np.fromfunction(lambda y, x: 1.0 + 0.1 * x + 0.37 * y, (H, W))  # the exact, per unit colour
    t_wet, t_dry = np.full((H, W), 0.5), np.ones((H, W))
    t_dry[CLOUD[1], CLOUD[0]] = 0.5
    k = np.array([[K[band_of(x)] for x in range(W)] for _ in range(H)])
    share = [c / sum(COLOUR) for c in COLOUR]  # of the pixel's light, per channel
    exact_total = v * sum(COLOUR)
    with tempfile.TemporaryDirectory() as tmp:
        run = pathlib.Path(tmp)
        wet, dry = run / "wet/out", run / "dry/out"
        (wet / "blender").mkdir(parents=True)
        dry.mkdir(parents=True)
        (wet / "blender/frame.json").write_text(json.dumps({"flash_colour": list(COLOUR)}))
        background_dry = 0.2
        layers_wet, layers_dry = {"T.Y": t_wet}, {"T.Y": t_dry}
        for c, s in zip("RGB", share):
            layers_wet["lightning." + c] = k * exact_total * s
            layers_dry["lightning." + c] = np.zeros((H, W))
            layers_wet["static." + c] = 0.05 * exact_total * s
            layers_dry["static." + c] = np.zeros((H, W))
            layers_wet["background." + c] = background_dry * t_wet
            layers_dry["background." + c] = np.full((H, W), background_dry)
            channel = np.zeros((H, W))
            channel[:, CORE_X] = 5.0
            layers_wet["channel." + c] = channel
            layers_dry["channel." + c] = channel
        write_exr(wet / "fulgur.exr", layers_wet)
        write_exr(dry / "fulgur.exr", layers_dry)
        cycles_dry = 0.3
        for seed, f in ((1, 1.1), (2, 0.9)):
            write_exr(dry / f"cycles_{seed}.exr", {c: np.full((H, W), cycles_dry) for c in "RGB"})
            write_exr(wet / f"cycles_{seed}.exr",
                      {c: cycles_dry * t_wet + f * exact_total * s for c, s in zip("RGB", share)})
        pixels = {f"{x},{y}": float(v[y, x]) for y in range(H) for x in range(W) if (x, y) != UNSAMPLED}
        exact_json = run / "exact.json"
        exact_json.write_text(json.dumps({"rain_pixels": pixels}))
        done = subprocess.run([sys.executable, str(SCRIPT), "compare-rain", str(run), str(exact_json)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"compare-rain failed ({done.returncode}):\n{done.stderr}")
    got = json.loads(done.stdout)

    counted = np.ones((H, W), bool)
    counted[CLOUD[1], CLOUD[0]] = counted[UNSAMPLED[1], UNSAMPLED[0]] = False
    failures = []

    def expect(name, want):
        have = got.get(name)
        if have is None or abs(have - want) > 1e-6 * max(1.0, abs(want)):
            failures.append(f"{name}: {have}, expected {want}")

    def region(prefix, mask):
        e = exact_total[mask].sum()
        expect(prefix + "pixels", int(mask.sum()))
        expect(prefix + "exact", e)
        expect(prefix + "fulgur_rain_over_exact", (k * exact_total)[mask].sum() / e)
        expect(prefix + "fulgur_whole_over_exact", ((k + 0.05) * exact_total)[mask].sum() / e)
        expect(prefix + "cycles_over_exact", 1.0)
        expect(prefix + "cycles_noise", 0.1)

    region("", counted)
    for b, (lo, hi) in enumerate(BANDS):
        cols = np.array([[band_of(x) == b for x in range(W)] for _ in range(H)])
        if (cols & counted).any():
            region("band_%d_%d_px_" % (lo, hi), cols & counted)
        elif any(key.startswith("band_%d_%d_px_" % (lo, hi)) for key in got):
            failures.append(f"band {lo}-{hi} px: reported, but no pixel lies in it")
    if failures:
        print(json.dumps(got, indent=1))
        raise SystemExit("compare-rain:\n  " + "\n  ".join(failures))
    print("compare-rain: all figures as constructed,", len(got) - 2, "of them")


if __name__ == "__main__":
    main()
