#!/bin/sh
# fulgur-bake under an MPI launcher, killed (SIGKILL, --stop-after) once its checkpoint holds
# some lights, then run again: it resumes, and the file is byte-identical to a plain
# one-process bake. A checkpoint of another scene is refused, naming its file, and not used.
# Usage: bake_restart.sh FULGUR-BAKE SCENES-DIR LAUNCHER [LAUNCHER-OPTIONS...]
set -u
bake=$1
scenes=$2
shift 2  # the rest: the MPI launcher and its options (mpirun -np 2 --oversubscribe)
scene=$scenes/test_iso_ss_ic.json
other=$scenes/test_aniso_ms_cg.json
rm -rf one.fgb two.fgb two.fgb.ckpt three.fgb three.fgb.ckpt log*.txt
fail() {
  echo "FAIL: $*"
  for f in log*.txt; do [ -e "$f" ] && { echo "--- $f"; cat "$f"; }; done
  exit 1
}

"$bake" "$scene" --threads 1 --no-checkpoint -o one.fgb > log1.txt 2>&1 || fail "the one-process bake failed"
"$@" "$bake" "$scene" --threads 1 -o two.fgb --stop-after 4 > log2.txt 2>&1 && fail "the killed bake returned 0"
[ -e two.fgb ] && fail "the killed bake left two.fgb"
ls two.fgb.ckpt/lights-*.fgb > /dev/null 2>&1 || fail "the killed bake left no chunk in two.fgb.ckpt/"
"$@" "$bake" "$scene" --threads 1 -o two.fgb > log3.txt 2>&1 || fail "the resumed bake failed"
grep -q "lights came from the checkpoint" log3.txt || fail "the second run did not resume"
grep -q "lights came from the checkpoint" log3.txt || fail "the second run took no light from the checkpoint"
cmp one.fgb two.fgb || fail "the resumed file differs from the one-process bake"
[ -e two.fgb.ckpt ] && fail "the checkpoint was left after a successful bake"

# Another scene's checkpoint where two.fgb's belongs: refused, two.fgb untouched.
"$@" "$bake" "$other" --threads 1 -o three.fgb --stop-after 2 > log4.txt 2>&1 && fail "the killed bake returned 0"
mv three.fgb.ckpt two.fgb.ckpt || fail "no checkpoint from the killed bake of the other scene"
"$@" "$bake" "$scene" --threads 1 -o two.fgb --force > log5.txt 2>&1 && fail "a foreign checkpoint was accepted"
grep -q "two.fgb.ckpt/lights-" log5.txt || fail "the refusal does not name the checkpoint's file"
grep -q "not used" log5.txt || fail "the refusal does not say the checkpoint was not used"
cmp one.fgb two.fgb || fail "a refused bake changed two.fgb"
# --fresh discards it and bakes.
"$@" "$bake" "$scene" --threads 1 -o two.fgb --force --fresh > log6.txt 2>&1 || fail "--fresh did not bake"
cmp one.fgb two.fgb || fail "the --fresh bake differs from the one-process bake"
echo "restart: killed, resumed, byte-identical; foreign checkpoint refused"
