#!/bin/sh
# The tools' outputs never replace an input or each other, a write that fails is exit 1, two
# bakes to one path leave one whole file, and no temporary or lock file is left behind.
# Usage: tool_outputs.sh FULGUR_BAKE FULGUR_SHOT SCENE.json WORKDIR
set -u
bake=$1 shot=$2 scene=$3 dir=$4
rm -rf "$dir" && mkdir -p "$dir" && cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cp "$scene" s.json
sed 's/"albedo": 0.99/"albedo": 0.5/' s.json > t.json
cmp -s s.json t.json && fail "t.json should differ from s.json"
cp s.json s.orig

# An output naming an input: exit 1, the input untouched, the error names both.
"$bake" s.json -o s.json 2> e1; test $? -eq 1 || fail "bake -o s.json: exit status"
grep -q "would overwrite the scene" e1 || fail "bake -o s.json: $(cat e1)"
"$bake" s.json -o x.fgb --report s.json 2> e2; test $? -eq 1 || fail "bake --report s.json: exit status"
"$bake" s.json -o x.fgb --report ./sub/../x.fgb 2> e3; test $? -eq 1 || fail "bake --report = -o: exit status"
grep -q "are the same file" e3 || fail "bake --report = -o: $(cat e3)"
"$shot" s.json --seed 1 --time 0 --size 8x8 -o s.json 2> e4; test $? -eq 1 || fail "shot -o s.json: exit status"
grep -q "would overwrite the scene" e4 || fail "shot -o s.json: $(cat e4)"
cmp -s s.json s.orig || fail "the scene was changed"
# The reference's derived images are outputs too.
"$shot" s.json --seed 1 --time 0 --size 8x8 -o r_diff.png --reference r.png 2> e5
test $? -eq 2 || fail "shot -o r_diff.png --reference r.png: exit status"
grep -q "same file" e5 || fail "shot -o REF_diff.png: $(cat e5)"

# A device that cannot be written: exit 1 before any work.
"$bake" s.json -o x.fgb --report /dev/full 2> e6; test $? -eq 1 || fail "bake --report /dev/full: exit status"
"$shot" s.json --seed 1 --time 0 --size 8x8 -o /dev/full 2> e7; test $? -eq 1 || fail "shot -o /dev/full: exit status"
grep -q "not a regular file" e7 || fail "shot -o /dev/full: $(cat e7)"
test -e x.fgb && fail "x.fgb written although an output was refused"

# Two bakes of different scenes to one path at once: both succeed in turn and the file is one
# of them, whole (the other scene sees it as stale, never as corrupt).
"$bake" s.json -o same.fgb --force > o1 2>&1 &
p1=$!
"$bake" t.json -o same.fgb --force > o2 2>&1
r2=$?
wait $p1
r1=$?
test $r1 -eq 0 && test $r2 -eq 0 || fail "concurrent bakes: exit $r1 $r2: $(cat o1 o2)"
"$bake" s.json -o same.fgb --dry-run > d1 2>&1 || fail "dry run s"
"$bake" t.json -o same.fgb --dry-run > d2 2>&1 || fail "dry run t"
n=$(cat d1 d2 | grep -c "same.fgb (up to date)")
test "$n" -eq 1 || fail "after concurrent bakes exactly one scene should find same.fgb up to date: $(grep output d1 d2)"

# Two renders of one scene that both need its bake at once: one bakes, the other waits for
# the lock and finds the file fresh; both render.
rm -f s.fgb
"$shot" s.json --seed 1 --time +0.002 --size 32x18 -o a.png > oa 2>&1 &
pa=$!
"$shot" s.json --seed 1 --time +0.002 --size 32x18 -o b.png > ob 2>&1
rb=$?
wait $pa
ra=$?
test $ra -eq 0 && test $rb -eq 0 || fail "concurrent shots: exit $ra $rb: $(cat oa ob)"
cmp -s a.png b.png || fail "concurrent shots of one frame differ"

left=$(ls -a | grep -E '\.(tmp|lock)$')
test -z "$left" || fail "left behind: $left"
echo "tool outputs: all checks passed"
