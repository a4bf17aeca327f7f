#!/usr/bin/env bash
# The cluster test: starts a single-node Slurm (local_cluster.sh), submits a
# 4-task array of the built-in box at a small size with submit.sh, waits for
# the merge job, compares the merge with a single-process render of the same
# samples and seed, re-runs one task by hand and checks that its part is the
# same file, and stops the daemons it started.
#
#   AETHER=target/release/aether tools/slurm/test_cluster.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
aether=${AETHER:?the aether binary}
dir=$(mktemp -d /tmp/aether-slurm.XXXXXX)
chmod 755 "$dir"
trap '"$here/local_cluster.sh" stop "$dir/cluster"' EXIT
eval "$("$here/local_cluster.sh" start "$dir/cluster")"
opts=(--size 24 --spp 8 --seed 5 -i path)
AETHER=$aether "$here/submit.sh" builtin --tasks 4 --out "$dir/merged.exr" "${opts[@]}"
for _ in $(seq 600); do
    [ -z "$(squeue -h 2>/dev/null)" ] && break
    sleep 0.2
done
[ -z "$(squeue -h)" ] || { echo "jobs still queued after 120 s:"; squeue; exit 1; }
[ -f "$dir/merged.exr" ] || { echo "no merged image"; cat "$dir"/merged-parts/*.log; exit 1; }
"$aether" render "${opts[@]}" -o "$dir/single.exr" > /dev/null
line=$("$aether" compare "$dir/single.exr" "$dir/merged.exr")
echo "$line"
# RMSE within 1e-6 of the mean: the same samples, summed in another order.
echo "$line" | awk '{ for (i = 1; i < NF; i++) { if ($i == "mean") m = $(i + 1); if ($i == "RMSE") r = $(i + 1) } }
    END { if (!(m > 0 && r <= 1e-6 * m)) { print "the merge differs from the single render"; exit 1 } }'
# A failed task re-run renders the same part.
"$aether" render "${opts[@]}" --shard 2/4 -o "$dir/again.exr" > /dev/null
# (EXR headers are written in no fixed order: the parts are compared, not the bytes.)
"$aether" compare "$dir/merged-parts/part-2.exr" "$dir/again.exr" | grep "the same part 2/4, every sum and count equal"
echo "cluster test passed: 4 tasks merged to the single render; a re-run task is the same part"
