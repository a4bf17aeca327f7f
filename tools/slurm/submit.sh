#!/usr/bin/env bash
# Submits a render as a Slurm job array of N parts and a merge job that runs
# when every part has succeeded:
#
#   tools/slurm/submit.sh SCENE.xml --tasks N [--out OUT.exr] [--parts DIR] [render options]
#
# SCENE.xml may be "builtin" for the built-in Cornell box. The render options
# (--spp, --seed, -i, --width, ...) go to every task; --shard and -o are set
# here. AETHER names the aether binary (default: target/release/aether, or
# aether on the PATH); SBATCH_ARGS adds options to both sbatch calls
# (a partition, a time limit, an account). Prints the two job ids.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
usage() { echo "usage: $0 SCENE.xml --tasks N [--out OUT.exr] [--parts DIR] [render options]" >&2; exit 2; }
[ $# -ge 1 ] || usage
scene=$1; shift
tasks='' out='' parts=''
render=()
while [ $# -gt 0 ]; do
    case $1 in
        --tasks) tasks=${2:?}; shift 2 ;;
        --out) out=${2:?}; shift 2 ;;
        --parts) parts=${2:?}; shift 2 ;;
        --shard|-o|--output) echo "$0: $1 is set by this script" >&2; exit 2 ;;
        *) render+=("$1"); shift ;;
    esac
done
[[ $tasks =~ ^[1-9][0-9]*$ ]] || { echo "$0: --tasks must be a positive integer" >&2; exit 2; }
if [ "$scene" != builtin ]; then
    [ -f "$scene" ] || { echo "$0: $scene: no such scene file" >&2; exit 2; }
    scene=$(cd "$(dirname "$scene")" && pwd)/$(basename "$scene")
fi
stem=$(basename "${scene%.xml}")
out=${out:-$PWD/$stem.exr}
case $out in /*) ;; *) out=$PWD/$out ;; esac
parts=${parts:-${out%.*}-parts}
case $parts in /*) ;; *) parts=$PWD/$parts ;; esac
mkdir -p "$parts"
aether=${AETHER:-}
if [ -z "$aether" ]; then
    if [ -x "$here/../../target/release/aether" ]; then aether=$here/../../target/release/aether
    else aether=$(command -v aether) || { echo "$0: set AETHER to the aether binary" >&2; exit 2; }; fi
fi
aether=$(cd "$(dirname "$aether")" && pwd)/$(basename "$aether")
# shellcheck disable=SC2086
array=$(sbatch --parsable ${SBATCH_ARGS:-} --array="0-$((tasks - 1))" \
    --output="$parts/task-%a.log" "$here/render.sbatch" "$aether" "$parts" "$scene" "${render[@]}")
array=${array%%;*}
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --dependency="afterok:$array" \
    --output="$parts/merge.log" "$here/merge.sbatch" "$aether" "$parts" "$out")
merge=${merge%%;*}
echo "render array $array ($tasks tasks, parts in $parts), merge $merge -> $out"
