#!/usr/bin/env bash
# Mutation table: does the suite fail when one light component is 5% wrong?
#
# Each mutation is a small patch in scripts/mutations/ (NAME.patch) that changes one component
# of the light by 5% (a solver's output, the truth's tally, the march's optical depth, the phase
# function's g). This script clones the committed HEAD into a scratch folder, builds the release
# preset once and runs the suite on it (it must pass), then for each mutation: applies the
# patch, rebuilds incrementally (as a developer would: the test caches of the previous build
# stay in the build tree, so a cache that outlives the code that made it would show here as a
# missed mutation), runs the suite, records the failing tests and reverts the patch.
#
#   scripts/mutation_table.sh [-L LABEL] [-R REGEX] [-o TABLE.md] [MUTATION...]
#
#   -L, -R     passed to ctest (run only a part of the suite; default: all of it)
#   -o FILE    also write the table (markdown) to FILE
#   MUTATION   names of patches in scripts/mutations (default: all)
#   FULGUR_MUTATION_DIR   scratch folder, kept (a second run reuses its build); default: a
#                         new one under /tmp, removed at the end
#
# Exit status 0 when every mutation fails at least one test, 1 when one is missed or a patch
# no longer applies, 2 on a usage or baseline error. Needs the packages of scripts/setup.sh.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
ctest_filter=()
out=""
while getopts "L:R:o:h" opt; do
    case $opt in
    L) ctest_filter+=(-L "$OPTARG") ;;
    R) ctest_filter+=(-R "$OPTARG") ;;
    o) out=$(realpath -m "$OPTARG") ;;
    *) sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
    esac
done
shift $((OPTIND - 1))
mutations=("$@")
if [ ${#mutations[@]} -eq 0 ]; then
    for p in "$repo"/scripts/mutations/*.patch; do mutations+=("$(basename "$p" .patch)"); done
fi
for m in "${mutations[@]}"; do
    [ -f "$repo/scripts/mutations/$m.patch" ] || { echo "mutation_table: no scripts/mutations/$m.patch" >&2; exit 2; }
done
if [ -n "$(git -C "$repo" status --porcelain --untracked-files=no)" ]; then
    echo "mutation_table: the working tree has uncommitted changes; the table is of HEAD $(git -C "$repo" rev-parse --short HEAD)" >&2
fi

scratch=${FULGUR_MUTATION_DIR:-}
if [ -z "$scratch" ]; then
    scratch=$(mktemp -d /tmp/fulgur-mutations.XXXXXX)
    trap 'rm -rf "$scratch"' EXIT
fi
src="$scratch/src"
if [ -d "$src/.git" ]; then  # a kept scratch folder: move it to HEAD, keep its build (incremental)
    git -C "$src" fetch -q "$repo" HEAD
    git -C "$src" checkout -q -- .
    git -C "$src" reset -q --hard FETCH_HEAD
else
    git clone -q "$repo" "$src"
fi
jobs=$(nproc)

build() { (cd "$src" && cmake --preset release > "$scratch/configure.log" && cmake --build --preset release -j "$jobs") > "$scratch/build.log" 2>&1; }
# Runs the suite; prints the names of the failing tests (none: empty).
suite() {
    (cd "$src" && ctest --preset release -j "$jobs" "${ctest_filter[@]}") > "$scratch/ctest.log" 2>&1 || true
    sed -n '/The following tests FAILED/,$p' "$scratch/ctest.log" | sed -n 's/^[[:space:]]*[0-9]* - \([^ ]*\) .*/\1/p' | sort -u
}

started=$(date +%s)
echo "mutation_table: baseline build and suite of $(git -C "$src" rev-parse --short HEAD) in $scratch" >&2
build || { echo "mutation_table: the baseline does not build (see $scratch/build.log)" >&2; exit 2; }
failing=$(suite)
if [ -n "$failing" ]; then
    echo "mutation_table: the baseline fails: $(echo $failing)" >&2
    exit 2
fi
grep -E "tests passed|Total Test time" "$scratch/ctest.log" >&2 || true

table="| mutation (5%) | failing tests | build + suite (s) |
| --- | --- | --- |"
missed=0
for m in "${mutations[@]}"; do
    t0=$(date +%s)
    if ! git -C "$src" apply "$repo/scripts/mutations/$m.patch"; then
        table+=$'\n'"| $m | **patch does not apply** | |"
        missed=1
        continue
    fi
    if build; then
        failing=$(suite)
        [ -n "$failing" ] || missed=1
        row=$(echo $failing | sed 's/ /, /g')
        row="${row:-**none**}"
    else
        row="**does not build** (see $scratch/build.log)"
        missed=1
    fi
    git -C "$src" checkout -q -- .
    table+=$'\n'"| $m | $row | $(( $(date +%s) - t0 )) |"
    echo "mutation_table: $m: $row" >&2
done
build || true  # leave the scratch build at HEAD

summary="Suite: ${ctest_filter[*]:-all tests} (release preset), incremental builds, $jobs jobs; \
$(( ($(date +%s) - started) / 60 )) min in all, baseline included."
echo "$table"
echo
echo "$summary"
if [ -n "$out" ]; then
    printf '%s\n\n%s\n' "$table" "$summary" > "$out"
fi
exit $missed
