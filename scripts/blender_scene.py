"""Renders a Fulgur frame (DIR/frame.json, written by `fulgur-shot --blender DIR`) with Blender
Cycles, as an independent reference for Fulgur's renderer.

    blender -b --factory-startup --python scripts/blender_scene.py -- DIR --out OUT.exr \
        [--samples N] [--seed S] [--threads T] [--light-radius M] [--max-light-loss F]
        [--single-scattering] [--channel drawn|hidden|alone] [--save-blend FILE.blend]

It builds the scene from scratch (the factory cube, light and camera are deleted), renders it
with Cycles on the CPU and writes OUT.exr: linear radiance in W m^-2 sr^-1 (metres are the world
unit), float32 RGBA, A = 1 (the world stays visible), no view transform. The last line on stdout
is one JSON object:
    {"name":"blender-scene","samples":N,"seed":S,"seconds":render wall time,"width":W,
     "height":H,"out":"...","light_radius":R,"light_loss":F}
(light_loss: the share of the first collisions the channel's sphere lights of radius R withhold
from the cloud, against true points; scripts/cycles_light_radius.py.)
An unreadable or malformed frame.json (or a missing VDB or grid) prints a message naming the
file and the field to stderr and exits with status 1 (sys.exit inside `blender --python` does
end Blender with that status: verified on Blender 3.4.1).

Units (checked by scripts/blender_calibrate.py against analytic cases on Cycles 3.4.1):
  * a point light's Power (W) is 4*pi times its radiant intensity (W/sr);
  * a sun's Strength is its irradiance (W/m^2) on a surface facing it;
  * Principled Volume: Density times the grid value is sigma_t per metre, Color is the
    single-scattering albedo (with Absorption Color black), Anisotropy is Henyey-Greenstein g;
  * Cycles puts a VDB's voxel (i,j,k) centre at index (i+0.5, j+0.5, k+0.5) of the grid's
    transform, half a voxel off OpenVDB's convention (centre at index (i,j,k)); the volume
    object is moved by -0.5 voxel on each axis to undo it (VOXEL_CENTRE_SHIFT below);
  * Cycles treats any volume coefficient <= 1e-5 per scene unit as zero (the Principled
    Volume's CLOSURE_WEIGHT_CUTOFF); the medium is therefore handed over K times denser in an
    object scaled K times up, which Cycles divides back out (density_scale, add_medium).
The VDB is read with pyopenvdb (Debian's Blender runs the system Python, which has it), checked
against frame.json (grid name and type, voxel size, origin, dims) and rewritten, density grid
only, with its transform divided by K, into a temporary directory (or next to --save-blend's
file, which then refers to it). A frame with rain (frame.json's "rain": its extinction per metre
on the density's grid, albedo and g) gets a second volume object the same way (rain.vdb).

The channel (frame.json's "channel": the stretches the frame draws, with the core's radius) is a
mesh of thin tubes that emits the core's radiance and is seen by camera rays only: its light in
the cloud is the point lights', so nothing is counted twice (`--channel drawn`, the default, for
a shot). `--channel hidden` leaves it out (the comparison with Fulgur's passes without the
channel, compare_cycles.py); `--channel alone` renders it alone through the media (no lights,
sun, sky or ground: the counterpart of Fulgur's channel pass, compare_cycles.py channel).

Why each Cycles setting is chosen is written next to it (configure_cycles and friends): the aim
is an unbiased estimate (no clamping, no bounce limit that matters, no denoiser, no adaptive
stopping, full-precision density, no density clipping, fine volume steps) of the same quantity
Fulgur's pixel is: the mean radiance over the pixel's footprint (a 1-pixel box filter).
"""
import json
import math
import os
import shutil
import sys
import tempfile
import time

import bpy
import mathutils
import numpy as np
import pyopenvdb as vdb  # Debian's python3-openvdb; Blender 3.4 (Debian) runs the system Python 3.11

PROG = "blender_scene.py"
# The channel's tubes: sides around each stretch, and the most stretches a frame may carry (a
# strike has hundreds; the bound keeps a hostile frame.json from building an unbounded mesh).
CHANNEL_SIDES = 8
MAX_CHANNEL_SEGMENTS = 200000

# Cycles samples a VDB grid with voxel (i,j,k)'s value at index-space position (i+0.5, j+0.5,
# k+0.5) (it treats the voxel as a cell [i, i+1] whose centre carries the value), whereas
# OpenVDB (and frame.json) put it at (i, j, k). Measured by scripts/blender_calibrate.py (the
# centroid of a small absorbing box seen along two axes, Cycles 3.4.1: +0.5 voxel on x, y and
# z without the correction). The volume object is translated by this many voxels to undo it.
# FULGUR_BLENDER_VOXEL_SHIFT overrides it (in voxels); blender_calibrate.py sets it to 0 to
# measure the raw offset.
VOXEL_CENTRE_SHIFT = float(os.environ.get("FULGUR_BLENDER_VOXEL_SHIFT", "-0.5"))

# The largest density copied densely to choose the channel's light radius (light_radius): 2^27
# voxels, 512 MB of float32 (a storm of 125 m voxels is 1.7M; beyond the limit the radius must be
# given).
DENSE_DENSITY_LIMIT = 1 << 27

# The medium's coefficients are handed to Cycles K times too large in a volume object scaled K
# times up, which Cycles divides back out (see add_medium): this moves Cycles' 1e-5 per-unit
# cutoff on volume coefficients down to 1e-5 / K per metre. K = min(1000, voxel_size / 0.05 m):
# Cycles 3.4 mis-renders a volume whose voxels are ~0.001 units in object space (measured: a
# cube's optical depth off by 8% at 0.001, right at 0.01 and above), so a voxel is kept >= 0.05
# units in object space. FULGUR_BLENDER_DENSITY_SCALE overrides K (blender_calibrate.py sets 1
# to show the cutoff).
def density_scale(voxel_size):
    env = os.environ.get("FULGUR_BLENDER_DENSITY_SCALE")
    if env:
        return float(env)
    return max(1.0, min(1000.0, voxel_size / 0.05))


# The sun's angular diameter: 0.536 degrees (the solar disc seen from the Earth, 32 arcmin),
# so the sun is a small disc rather than a delta direction, as in the real sky.
SUN_ANGLE_RAD = 0.00935

GROUND_SIZE_M = 2.0e6  # a 2000 km square plane: it reaches past the camera's clip_end (1e6 m)


class FrameError(Exception):
    pass


def warn(message):
    sys.stderr.write("%s: warning: %s\n" % (PROG, message))
    sys.stderr.flush()


def fail(message):
    sys.stdout.flush()
    sys.stderr.write("%s: error: %s\n" % (PROG, message))
    sys.stderr.flush()
    sys.exit(1)  # ends Blender with status 1 (verified with blender -b --python on 3.4.1)


# ----------------------------------------------------------------------------------------
# Command line and frame.json
# ----------------------------------------------------------------------------------------

def parse_args(argv):
    usage = ("usage: blender -b --factory-startup --python scripts/blender_scene.py -- DIR "
             "--out OUT.exr [--samples N] [--seed S] [--threads T] [--light-radius M] [--max-light-loss F] "
             "[--single-scattering] [--channel drawn|hidden|alone] [--save-blend FILE.blend]")
    args = {"dir": None, "out": None, "samples": 64, "seed": 0, "threads": 2, "save_blend": None,
            "light_radius": None, "max_light_loss": 0.01, "single": False, "channel": "drawn"}
    ints = {"--samples": ("samples", 1), "--seed": ("seed", 0), "--threads": ("threads", 1)}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in ("-h", "--help"):
            print(usage)
            sys.exit(0)
        if a in ("--out", "--save-blend", "--light-radius", "--max-light-loss", "--channel") or a in ints:
            if i + 1 >= len(argv):
                fail("%s needs a value\n%s" % (a, usage))
            v = argv[i + 1]
            if a == "--light-radius":
                try:
                    r = float(v)
                except ValueError:
                    fail("--light-radius: expected metres, got '%s'" % v)
                if not (math.isfinite(r) and r >= 0.0):
                    fail("--light-radius: %s is not a finite length >= 0" % v)
                args["light_radius"] = r
            elif a == "--max-light-loss":
                try:
                    f = float(v)
                except ValueError:
                    fail("--max-light-loss: expected a fraction, got '%s'" % v)
                if not (math.isfinite(f) and 0.0 <= f < 1.0):
                    fail("--max-light-loss: %s is not a fraction in [0, 1)" % v)
                args["max_light_loss"] = f
            elif a == "--channel":
                if v not in ("drawn", "hidden", "alone"):
                    fail("--channel: expected drawn, hidden or alone, got '%s'" % v)
                args["channel"] = v
            elif a == "--out":
                args["out"] = v
            elif a == "--save-blend":
                args["save_blend"] = v
            else:
                key, lo = ints[a]
                try:
                    n = int(v)
                except ValueError:
                    fail("%s: expected an integer, got '%s'" % (a, v))
                if n < lo or n > 2**31 - 1:
                    fail("%s: %d is out of range [%d, 2^31-1]" % (a, n, lo))
                args[key] = n
            i += 2
            continue
        if a == "--single-scattering":
            # Light scattered once in the volume only (volume bounces 0): the counterpart of
            # Fulgur's single-scattering term (fulgur-shot --off multiple), to split a
            # difference between the orders.
            args["single"] = True
            i += 1
            continue
        if a.startswith("-"):
            fail("unknown option '%s'\n%s" % (a, usage))
        if args["dir"] is not None:
            fail("more than one DIR ('%s' and '%s')\n%s" % (args["dir"], a, usage))
        args["dir"] = a
        i += 1
    if args["dir"] is None or args["out"] is None:
        fail("DIR and --out are required\n%s" % usage)
    return args


class Fields:
    """Typed access to frame.json; every error names the file and the field."""

    def __init__(self, path, root):
        self.path = path
        self.root = root

    def err(self, field, what):
        raise FrameError("%s: field '%s': %s" % (self.path, field, what))

    def get(self, obj, field, name, optional=False):
        if not isinstance(obj, dict):
            self.err(field.rsplit(".", 1)[0] if "." in field else field, "expected an object")
        if name not in obj:
            if optional:
                return None
            self.err(field, "missing")
        return obj[name]

    def flag(self, obj, field, name, default):
        """An optional true/false member (default when absent)."""
        v = self.get(obj, field, name, optional=True)
        if v is None:
            return default
        if not isinstance(v, bool):
            self.err(field, "expected true or false, got %s" % json.dumps(v))
        return v

    def number(self, value, field, lo=None, hi=None, lo_open=False):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.err(field, "expected a finite number, got %s" % json.dumps(value))
        value = float(value)
        if lo is not None and (value < lo or (lo_open and value == lo)):
            self.err(field, "%g is out of range (must be %s %g)" % (value, ">" if lo_open else ">=", lo))
        if hi is not None and value > hi:
            self.err(field, "%g is out of range (must be <= %g)" % (value, hi))
        return value

    def integer(self, value, field, lo, hi):
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            else:
                self.err(field, "expected an integer, got %s" % json.dumps(value))
        if value < lo or value > hi:
            self.err(field, "%d is out of range [%d, %d]" % (value, lo, hi))
        return value

    def vec(self, value, field, n=3, lo=None):
        if not isinstance(value, list) or len(value) != n:
            self.err(field, "expected an array of %d numbers, got %s" % (n, json.dumps(value)[:80]))
        return [self.number(v, "%s[%d]" % (field, i), lo=lo) for i, v in enumerate(value)]

    def string(self, value, field):
        if not isinstance(value, str) or not value:
            self.err(field, "expected a non-empty string, got %s" % json.dumps(value)[:80])
        return value


def read_frame(frame_dir):
    path = os.path.join(frame_dir, "frame.json")
    try:
        with open(path, "r", encoding="utf-8") as f:
            root = json.load(f)
    except OSError as e:
        raise FrameError("%s: cannot read: %s" % (path, e.strerror or e))
    except (ValueError, UnicodeDecodeError) as e:
        raise FrameError("%s: not valid JSON: %s" % (path, e))
    F = Fields(path, root)
    if not isinstance(root, dict):
        F.err("(root)", "expected an object")
    if F.get(root, "format", "format") != "fulgur-blender-frame":
        F.err("format", "expected \"fulgur-blender-frame\", got %s" % json.dumps(root.get("format")))
    version = F.get(root, "version", "version")
    if version != 1:
        F.err("version", "only version 1 is supported, got %s" % json.dumps(version))

    fr = {"path": path, "dir": frame_dir}
    img = F.get(root, "image", "image")
    fr["width"] = F.integer(F.get(img, "image.width", "width"), "image.width", 1, 65536)
    fr["height"] = F.integer(F.get(img, "image.height", "height"), "image.height", 1, 65536)

    cam = F.get(root, "camera", "camera")
    c = {}
    for k in ("position", "target", "up"):
        c[k] = F.vec(F.get(cam, "camera." + k, k), "camera." + k)
    c["fov"] = F.number(F.get(cam, "camera.vertical_fov_deg", "vertical_fov_deg"),
                        "camera.vertical_fov_deg", lo=0.0, hi=179.0, lo_open=True)
    fwd = mathutils.Vector(c["target"]) - mathutils.Vector(c["position"])
    if fwd.length == 0.0:
        F.err("camera.target", "equals camera.position (no view direction)")
    up = mathutils.Vector(c["up"])
    if up.length == 0.0 or fwd.normalized().cross(up.normalized()).length < 1e-6:
        F.err("camera.up", "is zero or parallel to the view direction")
    fr["camera"] = c

    # The cloud ("medium") and the rain under it ("rain", optional): each a VDB grid whose value
    # times `extinction` is sigma_t per metre, with its albedo and Henyey-Greenstein g.
    for key in ("medium", "rain"):
        med = F.get(root, key, key, optional=True)
        if med is None:
            fr[key] = None
            continue
        m = {"key": key}
        m["file"] = F.string(F.get(med, key + ".file", "file"), key + ".file")
        m["grid"] = F.string(F.get(med, key + ".grid", "grid"), key + ".grid")
        m["extinction"] = F.number(F.get(med, key + ".extinction", "extinction"), key + ".extinction", lo=0.0)
        m["albedo"] = F.number(F.get(med, key + ".albedo", "albedo"), key + ".albedo", lo=0.0, hi=1.0)
        m["g"] = F.number(F.get(med, key + ".g", "g"), key + ".g", lo=-1.0, hi=1.0)
        if abs(m["g"]) >= 1.0:
            F.err(key + ".g", "%g: |g| must be < 1" % m["g"])
        m["voxel_size"] = F.number(F.get(med, key + ".voxel_size", "voxel_size"), key + ".voxel_size",
                                   lo=0.0, lo_open=True)
        m["origin"] = F.vec(F.get(med, key + ".origin", "origin"), key + ".origin")
        dims = F.get(med, key + ".dims", "dims")
        if not isinstance(dims, list) or len(dims) != 3:
            F.err(key + ".dims", "expected an array of 3 integers")
        m["dims"] = [F.integer(d, "%s.dims[%d]" % (key, i), 1, 1 << 20) for i, d in enumerate(dims)]
        m["path"] = os.path.join(frame_dir, m["file"])
        if not os.path.isfile(m["path"]):
            F.err(key + ".file", "%s: no such file" % m["path"])
        fr[key] = m
    if fr["rain"] is not None and fr["medium"] is None:
        F.err("rain", "rain without a medium (it falls from the cloud's base)")

    flash = F.vec(F.get(root, "flash_colour", "flash_colour"), "flash_colour", lo=0.0)
    fr["flash_colour"] = flash
    lights = F.get(root, "lights", "lights")
    if not isinstance(lights, list):
        F.err("lights", "expected an array")
    fr["lights"] = []
    sp = F.get(root, "light_spacing", "light_spacing", optional=True)
    fr["light_spacing"] = 0.0 if sp is None else F.number(sp, "light_spacing", lo=0.0)
    for i, l in enumerate(lights):
        pos = F.vec(F.get(l, "lights[%d].position" % i, "position"), "lights[%d].position" % i)
        inten = F.number(F.get(l, "lights[%d].intensity" % i, "intensity"), "lights[%d].intensity" % i, lo=0.0)
        fr["lights"].append((pos, inten))

    # The channel the camera sees: [ax, ay, az, bx, by, bz, intensity per metre] per stretch.
    ch = F.get(root, "channel", "channel", optional=True)
    fr["channel"] = None
    if ch is not None:
        radius = F.number(F.get(ch, "channel.radius", "radius"), "channel.radius", lo=0.0, hi=1000.0, lo_open=True)
        segs = F.get(ch, "channel.segments", "segments")
        if not isinstance(segs, list):
            F.err("channel.segments", "expected an array")
        if len(segs) > MAX_CHANNEL_SEGMENTS:
            F.err("channel.segments", "%d stretches: at most %d" % (len(segs), MAX_CHANNEL_SEGMENTS))
        fr["channel"] = {"radius": radius, "segments": []}
        for i, sg in enumerate(segs):
            field = "channel.segments[%d]" % i
            v = F.vec(sg, field, n=7)
            F.number(v[6], field + "[6]", lo=0.0)   # W sr^-1 m^-1
            fr["channel"]["segments"].append(v)

    sun = F.get(root, "sun", "sun", optional=True)
    if sun is not None:
        d = F.vec(F.get(sun, "sun.direction", "direction"), "sun.direction")
        if mathutils.Vector(d).length == 0.0:
            F.err("sun.direction", "is the zero vector")
        e = F.vec(F.get(sun, "sun.irradiance_rgb", "irradiance_rgb"), "sun.irradiance_rgb", lo=0.0)
        fr["sun"] = {"direction": d, "irradiance_rgb": e}
    else:
        fr["sun"] = None

    sky = F.get(root, "sky", "sky", optional=True)
    if sky is not None:
        s = {"zenith_rgb": F.vec(F.get(sky, "sky.zenith_rgb", "zenith_rgb"), "sky.zenith_rgb", lo=0.0),
             "horizon_rgb": F.vec(F.get(sky, "sky.horizon_rgb", "horizon_rgb"), "sky.horizon_rgb", lo=0.0)}
        s["lights_cloud"] = F.flag(sky, "sky.lights_cloud", "lights_cloud", True)
        s["visible"] = F.flag(sky, "sky.visible", "visible", True)
        fr["sky"] = s
    else:
        fr["sky"] = None

    ground = F.get(root, "ground", "ground", optional=True)
    if ground is not None:
        fr["ground"] = {"height": F.number(F.get(ground, "ground.height", "height"), "ground.height"),
                        "albedo": F.number(F.get(ground, "ground.albedo", "albedo"), "ground.albedo",
                                           lo=0.0, hi=1.0)}
        fr["ground"]["lights_cloud"] = F.flag(ground, "ground.lights_cloud", "lights_cloud", True)
        pat = F.get(ground, "ground.pattern", "pattern", optional=True)
        if pat is not None:
            fr["ground"]["pattern"] = {
                "cell_m": F.number(F.get(pat, "ground.pattern.cell_m", "cell_m"), "ground.pattern.cell_m",
                                   lo=1.0, hi=1.0e6),
                "seed": F.integer(F.get(pat, "ground.pattern.seed", "seed"), "ground.pattern.seed", 0, 2**32 - 1),
                "low": F.number(F.get(pat, "ground.pattern.low", "low"), "ground.pattern.low", lo=0.0, hi=10.0),
                "span": F.number(F.get(pat, "ground.pattern.span", "span"), "ground.pattern.span", lo=0.0, hi=10.0),
                "tint_rgb": F.vec(F.get(pat, "ground.pattern.tint_rgb", "tint_rgb"), "ground.pattern.tint_rgb",
                                  lo=0.0)}
            q = fr["ground"]["pattern"]
            if fr["ground"]["albedo"] * (q["low"] + q["span"]) * max(q["tint_rgb"]) > 1.0:
                F.err("ground.pattern", "makes an albedo above 1 (albedo x (low + span) x tint)")
        haze = F.get(ground, "ground.haze_m", "haze_m", optional=True)
        if haze is not None:
            fr["ground"]["haze_m"] = F.number(haze, "ground.haze_m", lo=0.0, lo_open=True)
    else:
        fr["ground"] = None
    return fr


# ----------------------------------------------------------------------------------------
# Scene construction
# ----------------------------------------------------------------------------------------

def fold_colour(rgb, scale):
    """Return (rgb / max(rgb), scale * max(rgb)). Blender's light colour is [0, 1] only in the
    UI (RNA's hard limit is FLT_MAX and Cycles 3.4 does not clamp it: colour (0.5, 1, 2) at power
    P renders exactly as (0.25, 0.5, 1) at 2P), so this only keeps the colour in the UI's range."""
    m = max(rgb)
    if m <= 0.0:
        return (0.0, 0.0, 0.0), 0.0
    return tuple(c / m for c in rgb), scale * m


def clear_scene():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.lights, bpy.data.cameras, bpy.data.materials,
                 bpy.data.volumes, bpy.data.worlds):
        for block in list(coll):
            coll.remove(block)


def configure_cycles(scene, fr, args):
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"                    # the reference is rendered on the CPU
    cy.feature_set = "SUPPORTED"
    cy.samples = args["samples"]         # paths per pixel (--samples)
    cy.seed = args["seed"]               # --seed: independent runs use different seeds
    cy.use_animated_seed = False
    cy.sample_offset = 0
    cy.use_adaptive_sampling = False     # adaptive stopping ends pixels early on a noise
                                         # estimate; every pixel gets all N samples instead
    cy.use_denoising = False             # a denoiser is biased (it blurs and hallucinates)
    cy.use_preview_denoising = False
    cy.sampling_pattern = "PROGRESSIVE_MULTI_JITTER"  # stratified, unbiased
    cy.auto_scrambling_distance = False  # scrambling distance < 1 correlates pixels
    cy.scrambling_distance = 1.0
    # Bounces. In a thick medium of single-scattering albedo a a path scatters on average
    # ~1/(1-a) times before it is absorbed: 100 at a = 0.99, and the tail of that
    # distribution (long random walks that escape through a thin flank) carries light that a
    # cap would drop. 1024 makes the truncation negligible (0.99^1024 ~ 3e-5 of the energy).
    cy.max_bounces = 1024                # the overall cap; 1024 is RNA's hard maximum in 3.4
    cy.volume_bounces = 0 if args["single"] else 1024  # default 0: single scattering only, a heavy bias
    if args["channel"] == "alone":
        # Nothing lights the scene and the channel is seen by camera rays only: a path that
        # scatters can reach nothing, so it ends there (the camera ray's estimate of the
        # channel times the transmittance in front of it stays unbiased).
        cy.volume_bounces = 0
    cy.diffuse_bounces = 1024            # ground <-> cloud interreflection
    cy.glossy_bounces = 1024
    cy.transmission_bounces = 1024
    cy.transparent_max_bounces = 1024    # crossing the volume's bounding mesh counts as a
                                         # transparent bounce; never cut a path there
    cy.min_light_bounces = 0             # Russian roulette (unbiased) from the start
    cy.min_transparent_bounces = 0
    # No clamping: clamping a sample's contribution is biased (it darkens bright paths). The
    # factory default clamps indirect light at 10, which dims a lightning-lit cloud.
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    # Caustics on, no glossy blurring ("filter glossy" = blur_glossy): both are biasing
    # shortcuts. The scene has no glossy surfaces, so they cost nothing either way.
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.blur_glossy = 0.0
    # Lights whose estimated contribution is below the threshold are skipped; 0 = never skip
    # (there are hundreds of dim channel points whose sum matters).
    cy.light_sampling_threshold = 0.0
    # Volume ray marching: the per-object step size (set on the volume datablock, half a voxel
    # in the world, see add_medium) times this rate. 1 = the object's step as set.
    cy.volume_step_rate = 1.0
    cy.volume_preview_step_rate = 1.0
    # The march takes at most volume_max_steps steps through a volume (then Cycles stretches
    # the steps). The longest chord through the grid box is its diagonal; at a step of half a
    # voxel that is 2 * |dims| steps, plus margin.
    max_steps = 1024
    if fr["medium"] is not None:
        nx, ny, nz = fr["medium"]["dims"]
        max_steps = max(max_steps, int(math.ceil(2.0 * math.sqrt(nx * nx + ny * ny + nz * nz) * 1.25)) + 16)
    cy.volume_max_steps = min(max_steps, 65536)  # RNA's hard range is [2, 65536]
    # The pixel filter: a box of width 1 pixel, so a pixel is the mean radiance over its own
    # footprint (what Fulgur's pixel is), not a Blackman-Harris weighted 1.5-pixel mix of its
    # neighbours (the default).
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    cy.film_exposure = 1.0               # no scaling of the radiance
    cy.film_transparent_glass = False
    cy.use_auto_tile = True              # tiling does not change the estimate
    cy.debug_use_spatial_splits = False

    r = scene.render
    r.film_transparent = False           # the world stays visible; alpha is 1
    r.resolution_x = fr["width"]
    r.resolution_y = fr["height"]
    r.resolution_percentage = 100
    r.pixel_aspect_x = 1.0
    r.pixel_aspect_y = 1.0
    r.use_border = False
    r.use_motion_blur = False
    r.threads_mode = "FIXED"
    r.threads = args["threads"]          # --threads
    r.use_compositing = False            # no compositor, no sequencer: the render pass as is
    r.use_sequencer = False
    r.dither_intensity = 0.0             # no dither noise (it only touches 8-bit output anyway)
    r.use_persistent_data = False

    # Colour management: radiance out as is. 'Standard' with no look, exposure 0 and gamma 1
    # is the identity on scene-linear data; OpenEXR is written scene-linear in any case.
    vs = scene.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    vs.use_curve_mapping = False
    scene.sequencer_colorspace_settings.name = "Linear"

    im = r.image_settings
    im.file_format = "OPEN_EXR"
    im.color_mode = "RGBA"
    im.color_depth = "32"                # float32, not half
    im.exr_codec = "ZIP"                 # lossless
    im.use_preview = False
    r.use_file_extension = False         # write exactly --out
    r.use_overwrite = True


def add_camera(scene, fr):
    c = fr["camera"]
    cam = bpy.data.cameras.new("camera")
    cam.type = "PERSP"
    # Vertical field of view: fit the sensor vertically and set the vertical angle.
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(c["fov"])
    cam.shift_x = 0.0
    cam.shift_y = 0.0
    # Clipping: 1 m to 1000 km; nothing of the scene is nearer than a metre to the eye, and the
    # whole storm and the ground out to the horizon lie within 1e6 m.
    cam.clip_start = 1.0
    cam.clip_end = 1.0e6
    cam.dof.use_dof = False              # a pinhole, like Fulgur's camera
    ob = bpy.data.objects.new("camera", cam)
    pos = mathutils.Vector(c["position"])
    fwd = (mathutils.Vector(c["target"]) - pos).normalized()
    right = fwd.cross(mathutils.Vector(c["up"]).normalized()).normalized()
    up = right.cross(fwd)
    # A Blender camera looks along its local -Z with local +Y up and +X right.
    rot = mathutils.Matrix((right, up, -fwd)).transposed()
    ob.matrix_world = mathutils.Matrix.Translation(pos) @ rot.to_4x4()
    scene.collection.objects.link(ob)
    scene.camera = ob


def prepare_vdb(fr, m, out, K):
    """Checks DIR/<m.file> (m: frame.json's medium or rain) against frame.json and writes the
    copy Blender loads: its grid alone, the transform divided by K (density_scale; the object is
    scaled back up, see add_medium), every constant tile of a leafless grid split into leaves.
    Returns its path."""
    where = "%s: field '%s.%%s'" % (fr["path"], m["key"])
    try:
        grids, _meta = vdb.readAll(m["path"])
    except Exception as e:  # noqa: BLE001 - pyopenvdb raises plain RuntimeError/KeyError
        raise FrameError((where % "file") + ": cannot read %s as a VDB: %s" % (m["path"], e))
    by_name = {g.name: g for g in grids}
    grid = by_name.get(m["grid"])
    if grid is None:
        raise FrameError((where % "grid") + ": no grid '%s' in %s (it has: %s)"
                         % (m["grid"], m["path"], ", ".join(sorted(by_name)) or "no grids"))
    if grid.valueTypeName != "float":
        raise FrameError((where % "grid") + ": grid '%s' in %s holds %s values, not float"
                         % (m["grid"], m["path"], grid.valueTypeName))
    # The file's transform must be frame.json's: scale voxel_size, voxel (0,0,0) centred at
    # origin + 0.5 voxel_size, no rotation or shear.
    vs = m["voxel_size"]
    xf = grid.transform
    c0 = xf.indexToWorld((0, 0, 0))
    want = [o + 0.5 * vs for o in m["origin"]]
    tol = 1e-5 * max(vs, max(abs(v) for v in want))
    if any(abs(a - b) > tol for a, b in zip(c0, want)):
        raise FrameError((where % "origin") + ": %s puts voxel (0,0,0)'s centre at (%g, %g, %g), "
                         "frame.json's origin + 0.5 voxel_size is (%g, %g, %g)"
                         % ((m["path"],) + tuple(c0) + tuple(want)))
    for axis in range(3):
        ijk = [0, 0, 0]
        ijk[axis] = 1
        step = [a - b for a, b in zip(xf.indexToWorld(tuple(ijk)), c0)]
        expect = [vs if k == axis else 0.0 for k in range(3)]
        if any(abs(a - b) > 1e-5 * vs for a, b in zip(step, expect)):
            raise FrameError((where % "voxel_size") + ": %s's index-to-world transform is not a "
                             "scale by %g (axis %d steps by (%g, %g, %g))"
                             % ((m["path"], vs, axis) + tuple(step)))
    # A dense copy of the cloud for choosing the channel's light radius (light_radius), when the
    # frame has a channel and the copy fits in memory.
    if m["key"] == "medium" and fr["lights"] and m["dims"][0] * m["dims"][1] * m["dims"][2] <= DENSE_DENSITY_LIMIT:
        m["rho"] = np.zeros(tuple(m["dims"]), np.float32)
        grid.copyToArray(m["rho"], ijk=(0, 0, 0))
    lo, hi = grid.evalActiveVoxelBoundingBox()
    if grid.activeVoxelCount() > 0 and (min(lo) < 0 or any(h >= d for h, d in zip(hi, m["dims"]))):
        warn("%s: %s's active voxels span index (%d,%d,%d)..(%d,%d,%d), outside frame.json's "
             "%s.dims (%d, %d, %d)" % ((fr["path"], m["path"]) + tuple(lo) + tuple(hi) + (m["key"],) + tuple(m["dims"])))
    # A grid made only of constant tiles (no leaf nodes) renders empty in Cycles 3.4 (a grid with
    # some leaves renders its tiles fine): split each tile into leaves. Writing a different value
    # into a tile and then the tile's value back leaves a leaf behind (OpenVDB does not re-prune).
    if grid.leafCount() == 0 and grid.activeVoxelCount() > 0:
        acc = grid.getAccessor()
        tiles = [(it.min, it.max, it.value) for it in grid.citerOnValues() if it.count > 1]
        for (i0, j0, k0), (i1, j1, k1), v in tiles:
            for i in range(i0, i1 + 1, 8):
                for j in range(j0, j1 + 1, 8):
                    for k in range(k0, k1 + 1, 8):
                        acc.setValueOn((i, j, k), v + 1.0)
                        acc.setValueOn((i, j, k), v)
        warn("%s: grid '%s' had only constant tiles (Cycles renders those empty); split %d tiles "
             "into leaves" % (m["path"], m["grid"], len(tiles)))
    # Divide the transform by K (add_medium explains why).
    scaled = vdb.createLinearTransform(voxelSize=vs / K)
    scaled.translate(tuple(w / K for w in want))
    grid.transform = scaled
    grid.saveFloatAsHalf = False
    try:
        vdb.write(out, grids=[grid])
    except Exception as e:  # noqa: BLE001
        raise FrameError("cannot write the rescaled %s grid %s: %s" % (m["key"], out, e))
    return out


def add_medium(scene, fr, m, vdb_out):
    """The volume object of frame.json's medium or rain (m), from its rescaled grid at vdb_out.
    Where both are, Cycles adds their coefficients (its volume stack), as Fulgur's march does."""
    name = m["key"]
    vol = bpy.data.volumes.new(name)
    K = density_scale(m["voxel_size"])
    vol.filepath = prepare_vdb(fr, m, vdb_out, K)
    try:
        ok = vol.grids.load()
    except Exception:  # noqa: BLE001 - Blender raises plain RuntimeError here
        ok = False
    if not ok or m["grid"] not in [g.name for g in vol.grids]:
        raise FrameError("%s: field '%s.file': Blender cannot read the grid of %s "
                         "(rewritten as %s): %s" % (fr["path"], name, m["path"], vol.filepath,
                                                    vol.grids.error_message or "grid missing"))
    # The density is read at full float precision (the default, HALF, rounds rho to 11 bits)
    # and nothing is clipped (the default drops rho below 0.001, the thin fringe of a cloud,
    # which at 0.05/m over a few km of fringe is not negligible).
    vol.render.precision = "FULL"
    vol.render.clipping = 0.0
    # Density scale. Cycles' Principled Volume drops the whole medium (scattering and
    # extinction) wherever Density x grid value <= 1e-5 per scene unit (CLOSURE_WEIGHT_CUTOFF in
    # svm_node_principled_volume), and its scattering wherever albedo x that <= 1e-5: with
    # metres as scene units, any sigma_t below 1e-5 /m would be vacuum (rho < 2e-4 at
    # extinction 0.05; a whole thin test medium vanishes; measured by blender_calibrate.py).
    # In 'OBJECT' space Cycles divides a volume's coefficients by the object's scale *after*
    # that cutoff (object_volume_density), so: the grid is stored K times smaller (prepare_vdb),
    # the object scaled K times up (same voxels in the world), the shader's Density is
    # extinction x K, and the coefficients the integrator sees are extinction x rho per metre
    # again; the cutoff moves down to 1e-5 / K per metre (1e-8 /m for 125 m voxels).
    vol.render.space = "OBJECT"
    # Ray-marching step: half a voxel in the world (the trilinear density varies on the scale of
    # a voxel; half of it keeps the Riemann-sum error of the optical depth small). In 'OBJECT'
    # space the step is given in object units and multiplied by the object's scale.
    vol.render.step_size = 0.5 * m["voxel_size"] / K

    ob = bpy.data.objects.new(name, vol)
    ob.scale = (K, K, K)
    # Undo Cycles' half-voxel offset (see VOXEL_CENTRE_SHIFT); world units.
    shift = VOXEL_CENTRE_SHIFT * m["voxel_size"]
    ob.location = (shift, shift, shift)
    scene.collection.objects.link(ob)

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    # sigma_t = Density * grid value; scattering = sigma_t * Color, absorption =
    # sigma_t * (1 - Color) * (1 - Absorption Color): with Absorption Color black, Color is the
    # single-scattering albedo and sigma_t is exactly extinction * rho (times K, which the
    # object's scale divides out again).
    pv.inputs["Density"].default_value = m["extinction"] * K
    pv.inputs["Density Attribute"].default_value = m["grid"]
    a = m["albedo"]
    pv.inputs["Color"].default_value = (a, a, a, 1.0)
    pv.inputs["Color Attribute"].default_value = ""
    pv.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    pv.inputs["Anisotropy"].default_value = m["g"]       # Henyey-Greenstein g
    pv.inputs["Emission Strength"].default_value = 0.0
    pv.inputs["Blackbody Intensity"].default_value = 0.0
    pv.inputs["Temperature Attribute"].default_value = ""
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    # Distance + equiangular sampling with MIS (Cycles' default, unbiased; equiangular helps
    # near the point lights); trilinear interpolation of the density (what Fulgur does).
    mat.cycles.volume_sampling = "MULTIPLE_IMPORTANCE"
    mat.cycles.volume_interpolation = "LINEAR"
    mat.cycles.homogeneous_volume = False
    mat.cycles.volume_step_rate = 1.0    # the per-material multiplier of the step: none
    vol.materials.append(mat)


def light_radius(fr, args):
    """(radius, loss) of the channel's sphere lights: --light-radius, else the largest radius on
    cycles_light_radius.py's ladder (half the points' spacing, halved) whose share of the first
    collisions withheld from the cloud is at most --max-light-loss; loss None when the density is
    too large to measure it."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import cycles_light_radius

    m = fr["medium"]
    given = args["light_radius"]
    if m is None or not fr["lights"]:
        return (given if given is not None else 0.5 * fr["light_spacing"]), 0.0
    if "rho" not in m:
        r = given if given is not None else 0.5 * fr["light_spacing"]
        warn("%s: the density (%d x %d x %d voxels) is too large to measure what sphere lights of "
             "radius %g m withhold from the cloud; rendering with that radius (choose one with "
             "--light-radius)" % ((fr["path"],) + tuple(m["dims"]) + (r,)))
        return r, None
    got = cycles_light_radius.choose(m, [p for p, _ in fr["lights"]], [i for _, i in fr["lights"]],
                                     fr["light_spacing"], m["rho"], args["max_light_loss"],
                                     [given] if given is not None else None)
    return (given, got["ladder"].get("%g" % given, 0.0)) if given is not None else (got["radius"], got["loss"])


def add_point_lights(scene, fr, radius):
    """The channel's points. `radius` > 0 makes each a sphere light of that radius (Cycles keeps
    its power), which a scattering point can no longer come arbitrarily close to: a true point's
    1/d^2 spikes are what makes a light inside a cloud converge slowly (fireflies). The price is
    a bias: Cycles samples the sphere as a disk facing the receiver, which delivers less than the
    point within a few radii of it, so the medium around the channel collides less of its light
    (light_radius keeps that share below --max-light-loss)."""
    colour, scale = fold_colour(fr["flash_colour"], 1.0)
    coll = scene.collection
    for i, (pos, intensity) in enumerate(fr["lights"]):
        if intensity <= 0.0 or scale <= 0.0:
            continue
        light = bpy.data.lights.new("flash.%d" % i, "POINT")
        # Cycles' point light of power P (W) has radiant intensity P / (4 pi) W/sr.
        light.energy = 4.0 * math.pi * intensity * scale
        light.color = colour
        light.shadow_soft_size = radius   # 0: a true point light
        light.use_shadow = True
        light.cycles.cast_shadow = True
        light.cycles.max_bounces = 1024   # lights paths after any number of bounces
        light.specular_factor = 1.0
        light.diffuse_factor = 1.0
        light.volume_factor = 1.0
        ob = bpy.data.objects.new("flash.%d" % i, light)
        ob.location = pos
        coll.objects.link(ob)


def add_channel(scene, fr):
    """The channel as the camera sees it: one mesh of open tubes (CHANNEL_SIDES-gons around each
    stretch, the core's radius to their corners), emitting the core's radiance, intensity per
    metre / (2 radius) (Fulgur's bolt pass: a cylinder seen side-on). A polygon's projected width,
    averaged over the directions around its axis, is its perimeter / pi (Cauchy), 2 n r sin(pi / n)
    / pi for n sides, so the radiance is the intensity over that width: the flux a camera sees from
    the side is the cylinder's. Seen by camera rays only, and invisible to shadow rays: the point
    lights on its axis light the cloud, and the tube must not shadow them."""
    ch = fr["channel"]
    r = ch["radius"]
    colour, scale = fold_colour(fr["flash_colour"], 1.0)
    n = CHANNEL_SIDES
    width = 2.0 * n * r * math.sin(math.pi / n) / math.pi
    verts, faces, radiance = [], [], []
    for ax, ay, az, bx, by, bz, inten in ch["segments"]:
        a, b = mathutils.Vector((ax, ay, az)), mathutils.Vector((bx, by, bz))
        d = b - a
        if d.length == 0.0 or inten <= 0.0 or scale <= 0.0:
            continue
        d.normalize()
        u = d.cross(mathutils.Vector((1.0, 0.0, 0.0)) if abs(d.x) < 0.9 else mathutils.Vector((0.0, 1.0, 0.0)))
        u.normalize()
        v = d.cross(u)
        base = len(verts)
        for k in range(n):
            ang = 2.0 * math.pi * k / n
            off = r * (math.cos(ang) * u + math.sin(ang) * v)
            verts += [a + off, b + off]
        for k in range(n):
            k1 = (k + 1) % n
            faces.append((base + 2 * k, base + 2 * k1, base + 2 * k1 + 1, base + 2 * k + 1))
            radiance.append(inten * scale / width)
    if not faces:
        return
    mesh = bpy.data.meshes.new("channel")
    mesh.from_pydata([tuple(p) for p in verts], [], faces)
    attr = mesh.attributes.new("radiance", "FLOAT", "FACE")   # W m^-2 sr^-1 over the colour's max
    attr.data.foreach_set("value", radiance)
    mat = bpy.data.materials.new("channel")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emit = nt.nodes.new("ShaderNodeEmission")   # radiance = Color x Strength (the haze's calibration)
    emit.inputs["Color"].default_value = (colour[0], colour[1], colour[2], 1.0)
    att = nt.nodes.new("ShaderNodeAttribute")
    att.attribute_type = "GEOMETRY"
    att.attribute_name = "radiance"
    nt.links.new(att.outputs["Fac"], emit.inputs["Strength"])
    nt.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    if hasattr(mat.cycles, "sample_as_light"):
        mat.cycles.sample_as_light = False      # not a light: the points carry its light
    mesh.materials.append(mat)
    ob = bpy.data.objects.new("channel", mesh)
    scene.collection.objects.link(ob)
    ob.visible_diffuse = False
    ob.visible_glossy = False
    ob.visible_transmission = False
    ob.visible_volume_scatter = False
    ob.visible_shadow = False


def add_sun(scene, fr):
    colour, strength = fold_colour(fr["sun"]["irradiance_rgb"], 1.0)
    if strength <= 0.0:
        return
    light = bpy.data.lights.new("sun", "SUN")
    light.energy = strength               # Cycles' sun Strength is irradiance, W/m^2
    light.color = colour
    light.angle = SUN_ANGLE_RAD
    light.use_shadow = True
    light.cycles.cast_shadow = True
    light.cycles.max_bounces = 1024
    ob = bpy.data.objects.new("sun", light)
    # A sun light shines along its local -Z: point -Z along the travel direction.
    d = mathutils.Vector(fr["sun"]["direction"]).normalized()
    ob.rotation_mode = "QUATERNION"
    ob.rotation_quaternion = d.to_track_quat("-Z", "Y")
    scene.collection.objects.link(ob)


def add_world(scene, fr):
    world = bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputWorld")
    out.target = "ALL"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    sky = fr["sky"]
    if sky is None:
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)   # a black world
        world.cycles.sampling_method = "NONE"                     # nothing to sample
        return
    # radiance(d) = mix(horizon, zenith, sqrt(clamp(d.z, 0, 1))), d the unit view direction.
    # In a world shader the Texture Coordinate node's Generated output is the ray direction in
    # world space (unit length); checked by scripts/blender_calibrate.py (a pixel looking
    # straight up gets the zenith value, the horizon gets the horizon value).
    tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(tc.outputs["Generated"], sep.inputs["Vector"])
    clamp = nt.nodes.new("ShaderNodeMath")
    clamp.operation = "MAXIMUM"           # max(z, 0); z <= 1 for a unit vector
    clamp.inputs[1].default_value = 0.0
    clamp.use_clamp = True                # and clamp to [0, 1]
    nt.links.new(sep.outputs["Z"], clamp.inputs[0])
    sqrt = nt.nodes.new("ShaderNodeMath")
    sqrt.operation = "SQRT"
    nt.links.new(clamp.outputs["Value"], sqrt.inputs[0])
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.blend_type = "MIX"
    mix.use_clamp = False                 # sky radiances may exceed 1
    nt.links.new(sqrt.outputs["Value"], mix.inputs["Fac"])
    mix.inputs["Color1"].default_value = tuple(sky["horizon_rgb"]) + (1.0,)
    mix.inputs["Color2"].default_value = tuple(sky["zenith_rgb"]) + (1.0,)
    # Camera rays see the gradient (its horizon value below the horizon: Fulgur's backdrop
    # where no ground hides it), or black when the sky is not drawn; every other ray sees the
    # sky above the horizon only (Fulgur's sky light stops there: the ground's reflection is
    # no part of it).
    above = nt.nodes.new("ShaderNodeMath")
    above.operation = "GREATER_THAN"
    above.inputs[1].default_value = 0.0
    nt.links.new(sep.outputs["Z"], above.inputs[0])
    lighting = nt.nodes.new("ShaderNodeMixRGB")
    lighting.blend_type = "MULTIPLY"
    lighting.use_clamp = False
    lighting.inputs["Fac"].default_value = 1.0
    nt.links.new(mix.outputs["Color"], lighting.inputs["Color1"])
    nt.links.new(above.outputs["Value"], lighting.inputs["Color2"])
    path = nt.nodes.new("ShaderNodeLightPath")
    seen = nt.nodes.new("ShaderNodeMixRGB")
    seen.blend_type = "MIX"
    seen.use_clamp = False
    nt.links.new(path.outputs["Is Camera Ray"], seen.inputs["Fac"])
    nt.links.new(lighting.outputs["Color"], seen.inputs["Color1"])
    if sky["visible"]:
        nt.links.new(mix.outputs["Color"], seen.inputs["Color2"])
    else:
        seen.inputs["Color2"].default_value = (0.0, 0.0, 0.0, 1.0)
    nt.links.new(seen.outputs["Color"], bg.inputs["Color"])
    # Importance-sample the sky by a map of its radiance (unbiased, less noise). The sky is a
    # smooth gradient: a 256-wide map samples it as well as the default 1024 one and takes
    # ~0.1 s to build instead of ~2 s.
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 256
    world.cycles.max_bounces = 1024
    vis = world.cycles_visibility
    vis.camera = True
    lit = sky["lights_cloud"]
    # lights_cloud false: the sky is a backdrop only, seen by camera rays; it lights nothing.
    vis.diffuse = lit
    vis.glossy = lit
    vis.transmission = lit
    vis.scatter = lit


def pcg_hash(v):
    """common.glsl's hash_u32 on uint32 arrays (wrapping arithmetic)."""
    v = v.astype(np.uint32)
    state = v * np.uint32(747796405) + np.uint32(2891336453)
    word = ((state >> ((state >> np.uint32(28)) + np.uint32(4))) ^ state) * np.uint32(277803737)
    return (word >> np.uint32(22)) ^ word


def pattern_albedo(g, x, y):
    """The ground's albedo (RGB) at the points x, y (metres, arrays): background.glsl's
    ground_albedo with frame.json's pattern (render::GroundLook)."""
    q = g["pattern"]
    gx, gy = x / q["cell_m"], y / q["cell_m"]
    ix, iy = np.floor(gx), np.floor(gy)
    fx, fy = gx - ix, gy - iy
    fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
    seed = np.uint32(q["seed"])

    def corner(dx, dy):  # hash_unit(hash_u32(uvec3(ivec3(i, j, seed)))): ints as two's complement
        i = (ix + dx).astype(np.int64).astype(np.uint32)
        j = (iy + dy).astype(np.int64).astype(np.uint32)
        h = pcg_hash(i ^ pcg_hash(j ^ pcg_hash(np.full(i.shape, seed, dtype=np.uint32))))
        return (h >> np.uint32(8)).astype(np.float64) / 16777216.0

    v = (corner(0, 0) * (1 - fx) + corner(1, 0) * fx) * (1 - fy) + (corner(0, 1) * (1 - fx) + corner(1, 1) * fx) * fy
    return g["albedo"] * (q["low"] + q["span"] * v)[..., None] * np.array(q["tint_rgb"])


# The ground's pattern as an image texture (Cycles has no hash node): PATTERN_TEXELS per cell
# over PATTERN_CELLS cells around the point below the camera, linear between texel centres (the
# smoothstep between cell corners within ~0.1% of the albedo at 16 texels); beyond it the
# pattern's mean, low + span / 2 (Fulgur hazes the ground there: 78% at 60 km).
PATTERN_TEXELS = 16
PATTERN_CELLS = 80


def ground_albedo_node(nt, fr):
    """A node giving the ground's albedo colour: the pattern's texture where it covers the
    ground, its mean colour elsewhere, or the grey albedo without a pattern."""
    g = fr["ground"]
    q = g.get("pattern")
    if q is None:
        rgb = nt.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (g["albedo"], g["albedo"], g["albedo"], 1.0)
        return rgb.outputs[0]
    n = PATTERN_TEXELS * PATTERN_CELLS
    size = PATTERN_CELLS * q["cell_m"]
    cx, cy = fr["camera"]["position"][0], fr["camera"]["position"][1]
    x0 = (math.floor(cx / q["cell_m"]) - PATTERN_CELLS // 2) * q["cell_m"]
    y0 = (math.floor(cy / q["cell_m"]) - PATTERN_CELLS // 2) * q["cell_m"]
    t = (np.arange(n) + 0.5) * (size / n)
    X, Y = np.meshgrid(x0 + t, y0 + t)  # rows: y (Blender's images are stored bottom row first)
    alb = pattern_albedo(g, X, Y)
    img = bpy.data.images.new("ground_albedo", n, n, alpha=True, float_buffer=True)
    img.colorspace_settings.name = "Non-Color"  # albedo values, not a picture
    px = np.ones((n, n, 4), dtype=np.float32)
    px[..., :3] = alb
    img.pixels.foreach_set(px.ravel())
    img.pack()
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")  # object (= world) metres -> the image's [0, 1]^2
    mapping.vector_type = "POINT"
    mapping.inputs["Location"].default_value = (-x0 / size, -y0 / size, 0.0)
    mapping.inputs["Scale"].default_value = (1.0 / size, 1.0 / size, 1.0)
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Linear"
    tex.extension = "CLIP"  # transparent outside: the mean below
    nt.links.new(coord.outputs["Object"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    mean = nt.nodes.new("ShaderNodeRGB")
    m = [g["albedo"] * (q["low"] + 0.5 * q["span"]) * c for c in q["tint_rgb"]]
    mean.outputs[0].default_value = (m[0], m[1], m[2], 1.0)
    mix = nt.nodes.new("ShaderNodeMixRGB")
    nt.links.new(tex.outputs["Alpha"], mix.inputs["Fac"])
    nt.links.new(mean.outputs[0], mix.inputs["Color1"])
    nt.links.new(tex.outputs["Color"], mix.inputs["Color2"])
    return mix.outputs["Color"]


def add_haze(nt, fr, surface):
    """Fulgur's aerial perspective on the ground: seen by the camera at a distance t, its
    radiance mixed toward the sky's horizon radiance (black when the sky is not drawn) by
    1 - exp(-t / haze_m) (background.glsl's ground_haze). t is the camera ray's length (Light
    Path); rays that scattered do not see the ground (lights_cloud false), so only camera rays
    are hazed."""
    g, sky = fr["ground"], fr["sky"]
    h = sky["horizon_rgb"] if sky is not None and sky["visible"] else [0.0, 0.0, 0.0]
    path = nt.nodes.new("ShaderNodeLightPath")

    def math_node(op, a, b):
        n = nt.nodes.new("ShaderNodeMath")
        n.operation = op
        for k, v in enumerate((a, b)):
            if isinstance(v, float):
                n.inputs[k].default_value = v
            else:
                nt.links.new(v, n.inputs[k])
        return n.outputs[0]

    # 1 - exp(-t / haze_m), on camera rays only
    e = math_node("EXPONENT", math_node("MULTIPLY", path.outputs["Ray Length"], -1.0 / g["haze_m"]), 0.0)
    fac = math_node("MULTIPLY", math_node("SUBTRACT", 1.0, e), path.outputs["Is Camera Ray"])
    emit = nt.nodes.new("ShaderNodeEmission")  # radiance = Color x Strength
    emit.inputs["Color"].default_value = (h[0], h[1], h[2], 1.0)
    emit.inputs["Strength"].default_value = 1.0
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(fac, mix.inputs["Fac"])
    nt.links.new(surface, mix.inputs[1])
    nt.links.new(emit.outputs["Emission"], mix.inputs[2])
    return mix.outputs["Shader"]


def add_ground(scene, fr):
    g = fr["ground"]
    h = 0.5 * GROUND_SIZE_M
    z = g["height"]
    mesh = bpy.data.meshes.new("ground")
    mesh.from_pydata([(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)], [], [(0, 1, 2, 3)])  # normal +z
    mesh.update()
    mat = bpy.data.materials.new("ground")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(ground_albedo_node(nt, fr), bsdf.inputs["Color"])  # Lambertian, Fulgur's pattern
    bsdf.inputs["Roughness"].default_value = 0.0  # 0 = Lambert (not Oren-Nayar)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    surface = bsdf.outputs["BSDF"]
    if g.get("haze_m"):
        surface = add_haze(nt, fr, surface)
    nt.links.new(surface, out.inputs["Surface"])
    mesh.materials.append(mat)
    ob = bpy.data.objects.new("ground", mesh)
    scene.collection.objects.link(ob)
    if not g["lights_cloud"]:
        # Seen by the camera and casting shadows, but no light it reflects reaches anything
        # (Fulgur's cloud is not lit by the ground): scattered rays pass through it.
        ob.visible_diffuse = False
        ob.visible_glossy = False
        ob.visible_transmission = False
        ob.visible_volume_scatter = False


def build_scene(fr, args, vdb_out):
    """vdb_out: where the rescaled copy of the density grid is written (prepare_vdb); the rain's
    beside it (.rain.vdb for .density.vdb)."""
    if args["channel"] == "alone":
        # The channel through the media and nothing else: no light, a black world, no ground.
        fr.update(lights=[], sun=None, sky=None, ground=None)
    clear_scene()
    scene = bpy.context.scene
    scene.frame_set(1)
    configure_cycles(scene, fr, args)
    add_camera(scene, fr)
    add_world(scene, fr)
    if fr["medium"] is not None:
        add_medium(scene, fr, fr["medium"], vdb_out)
    if fr["rain"] is not None:
        assert vdb_out.endswith("density.vdb")
        add_medium(scene, fr, fr["rain"], vdb_out[:-len("density.vdb")] + "rain.vdb")
    radius, fr["light_loss"] = light_radius(fr, args)
    fr["light_radius"] = radius
    add_point_lights(scene, fr, radius)
    if fr["channel"] is not None and args["channel"] != "hidden":
        add_channel(scene, fr)
    if fr["sun"] is not None:
        add_sun(scene, fr)
    if fr["ground"] is not None:
        add_ground(scene, fr)
    return scene


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    args = parse_args(argv)
    out = os.path.abspath(args["out"])
    if not os.path.isdir(os.path.dirname(out)):
        fail("--out %s: directory %s does not exist" % (args["out"], os.path.dirname(out)))
    blend = os.path.abspath(args["save_blend"]) if args["save_blend"] else None
    if blend and not os.path.isdir(os.path.dirname(blend)):
        fail("--save-blend %s: directory %s does not exist" % (args["save_blend"], os.path.dirname(blend)))
    # The rescaled density grid Blender loads (prepare_vdb): next to the .blend when one is
    # saved (so that the .blend keeps working), else in a temporary directory removed at the end.
    tmp = None
    if blend:
        vdb_out = os.path.splitext(blend)[0] + ".density.vdb"
    else:
        tmp = tempfile.mkdtemp(prefix="fulgur-blender-")
        vdb_out = os.path.join(tmp, "density.vdb")
    try:
        try:
            fr = read_frame(args["dir"])
            scene = build_scene(fr, args, vdb_out)
        except FrameError as e:
            fail(str(e))
        if blend:
            bpy.ops.wm.save_as_mainfile(filepath=blend, check_existing=False)
        scene.render.filepath = out
        t0 = time.monotonic()
        bpy.ops.render.render(write_still=True)
        seconds = time.monotonic() - t0
        if not os.path.isfile(out):
            fail("--out %s: Blender did not write the image" % out)
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps({"name": "blender-scene", "samples": args["samples"], "seed": args["seed"],
                      "seconds": round(seconds, 3), "width": fr["width"], "height": fr["height"],
                      "out": out, "light_radius": fr["light_radius"], "light_loss": fr["light_loss"]},
                     separators=(",", ":")))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
