#!/usr/bin/env bash
# Runs every fuzz target for SECONDS (default 600) with debug assertions on, two at a time, and
# prints one line per target: runs executed and whether it crashed. Artifacts land in artifacts/.
# cargo-fuzz needs nightly features; RUSTC_BOOTSTRAP=1 enables them on the stable toolchain.
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
  cargo fuzz run -O -a "$t" -- -max_total_time="$secs" -rss_limit_mb=2048 >"logs/$t.log" 2>&1
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
