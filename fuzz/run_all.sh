#!/usr/bin/env bash
# Runs every fuzz target for SECONDS (default 600) with debug assertions on, two at a time, and
# prints one line per target: runs executed and whether it crashed. Artifacts land in artifacts/.
# cargo-fuzz needs nightly features; RUSTC_BOOTSTRAP=1 enables them on the stable toolchain.
# Single allocations up to 4 GiB are allowed: the mcap crate (0.26, via binrw) reserves a
# string's u32 length before reading it, so a damaged MCAP can reserve (not touch) 4 GiB in
# replay_schedule; anything larger is still reported.
set -u
cd "$(dirname "$0")"
secs=${1:-600}
export RUSTC_BOOTSTRAP=1
cargo fuzz build -O -a >/dev/null 2>&1 || { echo "cargo fuzz build failed (is cargo-fuzz installed?)"; exit 2; }
targets=$(cargo fuzz list)
mkdir -p logs
run() {
  local t=$1
  mkdir -p "corpus/$t"
  cargo fuzz run -O -a "$t" -- -max_total_time="$secs" -rss_limit_mb=2048 -malloc_limit_mb=4200 >"logs/$t.log" 2>&1
  local rc=$?
  local runs
  runs=$(grep -o 'Done [0-9]* runs' "logs/$t.log" | tail -1)
  if [ $rc -eq 0 ]; then echo "$t: ${runs:-?} in ${secs}s, no crash"; else echo "$t: CRASH (exit $rc), see fuzz/logs/$t.log"; fi
}
set -- $targets
while [ $# -gt 0 ]; do
  run "$1" &
  if [ $# -gt 1 ]; then run "$2" & shift; fi
  shift
  wait
done
