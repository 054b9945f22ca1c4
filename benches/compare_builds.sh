#!/usr/bin/env bash
# Decode, record and re-simulation speed of two work trees of hilrig, measured alternately in one
# run (so that the machine's load hits both alike), with the ratio new/old for each:
#
#   git worktree add ../before <commit>
#   benches/compare_builds.sh ../before . [ROUNDS]
#
# - decode: `cargo bench --bench decode_throughput` on the HDL-32E capture of ../shared/data
#   (points/s, single thread, in memory; best of 10 per round);
# - record: `cargo bench --bench record_throughput -- 100` (capture MB/s into MCAP);
# - resim: `benches/resim_speed.py strongest` (multiple of real time, idealized model).
# Each tree builds with its own target folder. Prints the best value of each tree over the rounds.
set -euo pipefail
old=$(realpath "$1")
new=$(realpath "$2")
rounds=${3:-3}
capture="${HILRIG_REAL_DATA:-$new/../shared/data}/velodyne/hdl32e_monterey.pcap"
[ -f "$capture" ] || { echo "needs $capture (../shared/data)" >&2; exit 2; }

decode() { (cd "$1" && cargo bench --quiet --bench decode_throughput -- "$capture" 10 2>/dev/null |
    python3 -c 'import json,sys; print(json.loads(sys.stdin.read().strip().splitlines()[-1])["points_per_second"])'); }
record() { (cd "$1" && cargo bench --quiet --bench record_throughput -- 100 2>/dev/null |
    awk '/^hilrig record/ { for (i = 1; i <= NF; i++) if ($i ~ /MB\/s/) { print $(i-1); exit } }'); }
resim() { (cd "$1" && python3 benches/resim_speed.py strongest 2>/dev/null |
    awk '/idealized/ { for (i = 1; i <= NF; i++) if ($i ~ /x$/) { sub(/x$/, "", $i); print $i; exit } }'); }

declare -A best
for r in $(seq "$rounds"); do
    for what in decode record resim; do
        for tree in old new; do
            dir=${!tree}
            v=$($what "$dir")
            echo "round $r $what $tree: $v" >&2
            key="$what-$tree"
            best[$key]=$(python3 -c "print(max(float('${best[$key]:-0}'), float('$v')))")
        done
    done
done
for what in decode record resim; do
    o=${best[$what-old]} n=${best[$what-new]}
    python3 -c "print(f'$what: old {float($o):.4g}, new {float($n):.4g}, new/old {float($n)/float($o):.3f}')"
done
