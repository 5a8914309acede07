#!/usr/bin/python3
"""scripts/blender_scene.py on an exported frame with rain (fulgur-shot --blender): it renders
(a tiny image, one sample: the rain's medium is built beside the cloud's), and refuses a
frame.json whose rain, ground or channel is malformed with exit status 1 and a message naming the field.
Usage: check_blender_frame.py BLENDER SCRIPT DIR (DIR: an export whose frame has rain)"""
import json
import os
import shutil
import subprocess
import sys
import tempfile


def run(blender, script, frame_dir, out):
    cmd = [blender, "-b", "--factory-startup", "--python", script, "--", frame_dir, "--out", out,
           "--samples", "1", "--threads", "1"]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300)


def main(blender, script, src):
    with open(os.path.join(src, "frame.json"), encoding="utf-8") as f:
        frame = json.load(f)
    assert frame["rain"] is not None, "%s: the frame has no rain" % src
    tmp = tempfile.mkdtemp(prefix="fulgur-blender-check-")
    try:
        # The frame as exported, at 8 x 8 pixels.
        ok_dir = os.path.join(tmp, "ok")
        shutil.copytree(src, ok_dir)
        small = dict(frame, image={"width": 8, "height": 8})
        with open(os.path.join(ok_dir, "frame.json"), "w", encoding="utf-8") as f:
            json.dump(small, f)
        r = run(blender, script, ok_dir, os.path.join(tmp, "ok.exr"))
        assert r.returncode == 0, "the exported frame did not render:\n" + r.stderr[-2000:]
        assert os.path.isfile(os.path.join(tmp, "ok.exr")), "no image written"

        # Malformed rain entries: each refused, naming the field.
        bad = [("rain.g", lambda j: j["rain"].update(g=1.5)),
               ("rain.dims", lambda j: j["rain"].update(dims=[4, 4])),
               ("rain.file", lambda j: j["rain"].update(file="missing.vdb")),
               ("rain.grid", lambda j: j["rain"].update(grid="not_there")),
               ("rain", lambda j: j.update(medium=None)),
               ("ground.pattern.cell_m", lambda j: j["ground"]["pattern"].update(cell_m=0)),
               ("ground.pattern.seed", lambda j: j["ground"]["pattern"].update(seed=-3)),
               ("ground.pattern.tint_rgb", lambda j: j["ground"]["pattern"].update(tint_rgb=[1, 2])),
               ("ground.pattern", lambda j: j["ground"]["pattern"].update(tint_rgb=[20, 20, 20])),
               ("ground.haze_m", lambda j: j["ground"].update(haze_m=-1)),
               ("channel.radius", lambda j: j.update(channel={"radius": 0, "segments": []})),
               ("channel.segments[1]", lambda j: j.update(channel={"radius": 2, "segments": [
                   [0, 0, 0, 0, 0, 100, 1e5], [0, 0, 100, 0, 0, 200]]}))]
        for field, spoil in bad:
            d = os.path.join(tmp, field.replace(".", "_"))
            shutil.copytree(src, d)
            j = json.loads(json.dumps(small))
            spoil(j)
            with open(os.path.join(d, "frame.json"), "w", encoding="utf-8") as f:
                json.dump(j, f)
            r = run(blender, script, d, os.path.join(tmp, "bad.exr"))
            assert r.returncode == 1, "%s: exit status %d, expected 1" % (field, r.returncode)
            assert "'%s" % field in r.stderr or "field '%s" % field in r.stderr, \
                "%s: the message does not name it:\n%s" % (field, r.stderr[-1000:])
        print("blender_scene.py: the frame with rain renders; %d malformed rain, ground and channel entries refused, each "
              "named" % len(bad))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3])
