#!/usr/bin/env python3
"""Corrupt copies of an OpenVDB file through the tools, as a hostile user would.

Writes N mutants of VDB (each one random single-bit flip anywhere in the file, or in its
first REGION bytes, positions drawn from SEED), points a copy of SCENE's "cloud.vdb" at each and runs every TOOL on it
(e.g. "fulgur-bake --dry-run", "fulgur-preview -o DIR"). Each run is timed and its peak
resident size read from the kernel (the tool and its OpenVDB reading child alike).

Prints one JSON line per run and a summary: how many loaded (exit 0), were refused naming
the file (exit 1 with the mutant's path in the message), or ended otherwise (an abort, a
signal, a refusal that does not name the file), the slowest refusal and the largest peak.
Exit status 1 when any run ended otherwise or passed the --max-seconds / --max-mib bounds.

  scripts/vdb_mutants.py --vdb content/clouds/storm-cell.vdb \\
      --scene tests/apps/scenes/test_vdb_cloud.json --count 190 --seed 2027 --region 12000 \\
      --tool "build/release/app/fulgur-bake --dry-run" --out /tmp/mutants
"""
import argparse
import json
import os
import random
import shlex
import subprocess
import sys
import time


def peak_mib(cmd, cwd):
    """Runs cmd under /usr/bin/time -f %M (KiB, the largest of the process and its children)."""
    full = ["/usr/bin/time", "-f", "FULGUR_PEAK_KIB %M"] + cmd
    t0 = time.monotonic()
    proc = subprocess.run(full, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    seconds = time.monotonic() - t0
    err = proc.stderr.decode("utf-8", "replace")
    kib = 0
    lines = []
    for line in err.splitlines():
        if line.startswith("FULGUR_PEAK_KIB "):
            kib = int(line.split()[1])
        elif not line.startswith("Command exited with non-zero status") and not line.startswith("Command terminated"):
            lines.append(line)
    return proc.returncode, "\n".join(lines), seconds, kib / 1024.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vdb", required=True)
    ap.add_argument("--scene", required=True, help="a scene whose cloud is a VDB (its cloud.vdb is replaced)")
    ap.add_argument("--count", type=int, default=190)
    ap.add_argument("--region", type=int, default=0,
                    help="flip bits only in the first REGION bytes (the header, descriptors and tree topology; "
                         "0: anywhere)")
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--tool", action="append", required=True, help="a command; the scene is appended")
    ap.add_argument("--out", required=True, help="scratch directory for the mutants")
    ap.add_argument("--max-seconds", type=float, default=60.0)
    ap.add_argument("--max-mib", type=float, default=4096.0)
    a = ap.parse_args()

    os.makedirs(a.out, exist_ok=True)
    original = open(a.vdb, "rb").read()
    scene = json.load(open(a.scene))
    rng = random.Random(a.seed)
    counts = {"loaded": 0, "refused": 0, "other": 0}
    slowest = 0.0
    largest = 0.0
    over = 0
    for i in range(a.count):
        at = rng.randrange(a.region if 0 < a.region < len(original) else len(original))
        bit = rng.randrange(8)
        data = bytearray(original)
        data[at] ^= 1 << bit
        vdb = os.path.abspath(os.path.join(a.out, f"m{i:04d}_{at}_{bit}.vdb"))
        with open(vdb, "wb") as f:
            f.write(data)
        s = json.loads(json.dumps(scene))
        s["cloud"]["vdb"] = vdb
        scene_path = os.path.join(a.out, f"m{i:04d}.json")
        with open(scene_path, "w") as f:
            json.dump(s, f)
        for tool in a.tool:
            cmd = shlex.split(tool) + [os.path.abspath(scene_path)]
            rc, err, seconds, mib = peak_mib(cmd, a.out)
            if rc == 0:
                outcome = "loaded"
            elif rc == 1 and vdb in err:
                outcome = "refused"
            else:
                outcome = "other"
            counts[outcome] += 1
            if outcome == "refused":
                slowest = max(slowest, seconds)
            largest = max(largest, mib)
            if seconds > a.max_seconds or mib > a.max_mib:
                over += 1
            last = err.strip().splitlines()[-1] if err.strip() else ""
            print(json.dumps({"mutant": i, "byte": at, "bit": bit, "tool": shlex.split(tool)[0].split("/")[-1],
                              "rc": rc, "outcome": outcome, "seconds": round(seconds, 3),
                              "peak_mib": round(mib, 1), "message": last[:300]}), flush=True)
        os.remove(vdb)
        os.remove(scene_path)
    summary = {"summary": True, "mutants": a.count, "seed": a.seed, "runs": sum(counts.values()), **counts,
               "slowest_refusal_s": round(slowest, 3), "largest_peak_mib": round(largest, 1), "over_bounds": over}
    print(json.dumps(summary))
    return 1 if counts["other"] or over else 0


if __name__ == "__main__":
    sys.exit(main())
