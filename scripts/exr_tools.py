#!/usr/bin/python3
"""Small OpenEXR helpers for the Blender reference renders (OpenImageIO + numpy, plain python3).

    read_exr(path) -> (float64 array H x W x C, dict of header attributes)
    python3 scripts/exr_tools.py stats A.exr [B.exr ...]   # per-channel mean/max/min, one JSON line each

Row 0 of the array is the top row of the image (OpenImageIO's order); channels are in the file's
order (Blender writes R, G, B, A).
"""
import json
import sys

import numpy as np
import OpenImageIO as oiio


def read_exr(path):
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError("%s: cannot open: %s" % (path, oiio.geterror()))
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if pixels is None:
            raise OSError("%s: cannot read pixels: %s" % (path, inp.geterror()))
        header = {a.name: a.value for a in spec.extra_attribs}
        header.update({"width": spec.width, "height": spec.height,
                       "channelnames": list(spec.channelnames), "format": str(spec.format)})
    finally:
        inp.close()
    img = np.asarray(pixels, dtype=np.float64).reshape(spec.height, spec.width, spec.nchannels)
    return img, header


def stats(path):
    img, header = read_exr(path)
    names = header["channelnames"]
    out = {"file": path, "width": header["width"], "height": header["height"], "channels": {}}
    for c, name in enumerate(names):
        ch = img[:, :, c]
        out["channels"][name] = {"mean": float(ch.mean()), "max": float(ch.max()), "min": float(ch.min())}
    out["finite"] = bool(np.isfinite(img).all())
    return out


def main(argv):
    if len(argv) < 2 or argv[0] != "stats":
        sys.stderr.write("usage: python3 scripts/exr_tools.py stats A.exr [B.exr ...]\n")
        return 2
    status = 0
    for path in argv[1:]:
        try:
            print(json.dumps(stats(path)))
        except OSError as e:
            sys.stderr.write("exr_tools.py: %s\n" % e)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
