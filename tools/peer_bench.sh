#!/usr/bin/env bash
# Speed against other renderers: for each workload, our samples/s, theirs
# and the ratio (ours / theirs), each the median of RUNS runs taken in turn
# (ours, theirs, ours, theirs, ...). Peers that are not installed are
# skipped, saying so.
#
#   tools/peer_bench.sh
#   RUNS=5 AETHER=target/release/aether PYTHON=venv/bin/python SMALLVCM=/opt/smallvcm/smallvcm tools/peer_bench.sh
#
# Workloads (512x512 each):
#   cbox      ../shared/scenes/aether/cbox/cbox_path.xml, path tracing, 16 spp,
#             max depth 6; against Mitsuba 3's `path` (scalar_rgb, and
#             llvm_ad_rgb where it loads), the scene rewritten for Mitsuba 3
#             by tools/peer_bench_mitsuba.py (Mitsuba's max_depth counts edges
#             as our --max-depth does); only mi.render is timed, after a 1 spp
#             warm-up render in the same process.
#   smallvcm  scenes/smallvcm_box.xml, BDPT and path tracing, 8 spp, max depth
#             10; against SmallVCM's `bpt` and `pt` with `-i 8` (one iteration
#             is one sample per pixel; its paths have at most 10 segments,
#             our --max-depth 10). SmallVCM's own "done in" is processor time
#             summed over its threads, so its process is timed by the clock
#             on the wall instead (building its 30-primitive scene and writing
#             a 1 MB image take milliseconds).
# Our figure is the samples/s that `aether render` prints (the render's time
# on the wall, without loading the scene).
#
# Environment:
#   AETHER    our program (default target/release/aether, built with cargo if missing)
#   PYTHON    a Python that can import mitsuba (default python3)
#   SMALLVCM  SmallVCM's program (no default: skipped without it)
#   RUNS      runs of each program per workload (default 3, at least 1)
#
# Getting the peers (none of their code belongs in this repository):
#   Mitsuba 3:   python3 -m venv /opt/venv-mi && /opt/venv-mi/bin/pip install mitsuba
#                then PYTHON=/opt/venv-mi/bin/python
#   llvm_ad_rgb: Debian's LLVM 19 (apt-get install libllvm19) and
#                DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so
#                (set to that by default here when the file exists)
#   SmallVCM:    clone github.com/SmallVCM/SmallVCM outside this repository,
#                append the entry `Scene::kBothSmallSpheres | Scene::kLightCeiling`
#                to g_SceneConfigs in src/config.hxx (its --report mode insists
#                on exactly 4 scenes; only the -s mode is used here), build
#                with `g++ -O3 -std=c++0x -fopenmp src/smallvcm.cxx -o smallvcm`,
#                then SMALLVCM=/path/to/smallvcm. The scene is found by its
#                name in `smallvcm -h` ("small spheres + ceiling (area)").
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
AETHER=${AETHER:-$ROOT/target/release/aether}
PYTHON=${PYTHON:-python3}
SMALLVCM=${SMALLVCM:-}
RUNS=${RUNS:-3}
if [[ -z ${DRJIT_LIBLLVM_PATH:-} && -e /usr/lib/x86_64-linux-gnu/libLLVM-19.so ]]; then
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so
fi

CBOX=$ROOT/../shared/scenes/aether/cbox/cbox_path.xml
BOX=$ROOT/scenes/smallvcm_box.xml
PIXELS=$((512 * 512))

TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

if [[ ! -x $AETHER ]]; then
    if [[ $AETHER == "$ROOT/target/release/aether" ]]; then
        (cd "$ROOT" && cargo build --release -p integrators --bin aether)
    else
        echo "AETHER=$AETHER is not an executable" >&2
        exit 1
    fi
fi

# The median of the numbers on standard input, one a line.
median() {
    sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "nan"; else if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}

# Our samples/s: SCENE INTEGRATOR SPP DEPTH.
ours() {
    local out
    out=$("$AETHER" render "$1" -i "$2" --spp "$3" --max-depth "$4" -o "$TMP/ours.exr" 2>&1) || {
        echo "$out" >&2
        return 1
    }
    # "...: 1.80 s, 290944 samples/s, 2.36 Mrays/s"
    sed -n 's/.* \([0-9.e+]*\) samples\/s.*/\1/p' <<<"$out" | tail -n 1
}

# Mitsuba 3's samples/s: VARIANT SCENE SPP DEPTH.
mitsuba() {
    "$PYTHON" "$ROOT/tools/peer_bench_mitsuba.py" "$1" "$2" "$3" "$4"
}

# SmallVCM's samples/s: ALGORITHM ITERATIONS (its scene id is $VCM_SCENE).
smallvcm() {
    local start end
    start=$(date +%s.%N)
    "$SMALLVCM" -s "$VCM_SCENE" -a "$1" -i "$2" -o "$TMP/smallvcm.hdr" >/dev/null
    end=$(date +%s.%N)
    awk -v n=$((PIXELS * $2)) -v a="$start" -v b="$end" 'BEGIN { printf "%.0f\n", n / (b - a) }'
}

# One workload: NAME, then our command and each peer's as
# "LABEL=COMMAND ARGS..." words. The programs run in turn, RUNS times; the
# medians and ratios are printed as rows of the table.
workload() {
    local name=$1 ours_cmd=$2
    shift 2
    local i label cmd v
    : >"$TMP/ours.txt"
    for label in "$@"; do : >"$TMP/peer-${label%%=*}.txt"; done
    for ((i = 1; i <= RUNS; i++)); do
        v=$($ours_cmd)
        echo "$v" >>"$TMP/ours.txt"
        local line="  $name, run $i/$RUNS: ours $v"
        for label in "$@"; do
            cmd=${label#*=}
            v=$($cmd)
            echo "$v" >>"$TMP/peer-${label%%=*}.txt"
            line+=", ${label%%=*} $v"
        done
        echo "$line" >&2
    done
    local mine theirs
    mine=$(median <"$TMP/ours.txt")
    for label in "$@"; do
        theirs=$(median <"$TMP/peer-${label%%=*}.txt")
        awk -v w="$name" -v p="${label%%=*}" -v a="$mine" -v b="$theirs" \
            'BEGIN { printf "%-34s %12.0f  %-22s %12.0f  %6.2f\n", w, a, p, b, a / b }' >>"$TMP/table.txt"
    done
}

echo "aether: $AETHER; $RUNS runs each, medians; $(nproc) cores"
: >"$TMP/table.txt"

# Path tracing on the Cornell box, against Mitsuba 3.
if [[ ! -f $CBOX ]]; then
    echo "cbox: skipped ($CBOX is absent)"
elif ! "$PYTHON" -c 'import mitsuba' 2>/dev/null; then
    echo "Mitsuba 3: skipped ($PYTHON cannot import mitsuba; set PYTHON to a Python that can)"
else
    peers=()
    for variant in scalar_rgb llvm_ad_rgb; do
        if why=$("$PYTHON" -c "import mitsuba as mi; mi.set_variant('$variant')" 2>&1); then
            peers+=("mitsuba-$variant=mitsuba $variant $CBOX 16 6")
        else
            echo "Mitsuba 3 $variant: unavailable ($(tail -n 1 <<<"$why"))"
        fi
    done
    if ((${#peers[@]})); then
        workload "cbox path, 16 spp, depth 6" "ours $CBOX path 16 6" "${peers[@]}"
    fi
fi

# BDPT and path tracing on SmallVCM's box, against SmallVCM.
if [[ -z $SMALLVCM ]]; then
    echo "SmallVCM: skipped (set SMALLVCM to its program)"
elif [[ ! -x $SMALLVCM ]]; then
    echo "SmallVCM: skipped ($SMALLVCM is not an executable)"
else
    # (its -h exits with status 1)
    VCM_SCENE=$({ "$SMALLVCM" -h || true; } | sed -n 's/^ *\([0-9][0-9]*\) *small spheres + ceiling (area)$/\1/p' | head -n 1)
    if [[ -z $VCM_SCENE ]]; then
        echo "SmallVCM: skipped (its -h lists no scene \"small spheres + ceiling (area)\": add Scene::kBothSmallSpheres | Scene::kLightCeiling to g_SceneConfigs)"
    else
        workload "smallvcm_box bdpt, 8 spp, depth 10" "ours $BOX bdpt 8 10" "smallvcm-bpt=smallvcm bpt 8"
        workload "smallvcm_box path, 8 spp, depth 10" "ours $BOX path 8 10" "smallvcm-pt=smallvcm pt 8"
    fi
fi

if [[ -s $TMP/table.txt ]]; then
    echo
    printf "%-34s %12s  %-22s %12s  %6s\n" "workload" "ours (1/s)" "peer" "theirs (1/s)" "ratio"
    cat "$TMP/table.txt"
fi
