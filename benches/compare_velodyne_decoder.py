#!/usr/bin/env python3
"""Decode throughput: hilrig against velodyne-decoder, same capture, same run (issue 2, item 8).

Both decode from bytes already in memory on one thread; velodyne-decoder through its documented
`read_pcap` (C++ core), hilrig through the pipeline `hilrig decode` runs (capture demux, packet
decode, point geometry). Rounds alternate between the two so that load on this shared machine
hits both alike; the best round of each is reported, then the ratio.

usage: benches/compare_velodyne_decoder.py [CAPTURE] [ROUNDS]
   (default capture: $HILRIG_REAL_DATA/velodyne/hdl32e_monterey.pcap; run with the venv python)
"""
import importlib.metadata
import io
import json
import os
import subprocess
import sys
import time

import velodyne_decoder as vd

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
data = os.environ.get("HILRIG_REAL_DATA", os.path.join(root, "..", "shared", "data"))
capture = sys.argv[1] if len(sys.argv) > 1 else os.path.join(data, "velodyne", "hdl32e_monterey.pcap")
rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 5

subprocess.run(["cargo", "build", "--release", "--bench", "decode_throughput", "--quiet"], cwd=root, check=True)
exe = subprocess.run(
    ["cargo", "bench", "--bench", "decode_throughput", "--no-run", "--message-format=json", "--quiet"],
    cwd=root, check=True, capture_output=True, text=True).stdout
binary = [json.loads(l)["executable"] for l in exe.splitlines()
          if l.startswith("{") and json.loads(l).get("executable") and "decode_throughput" in l][-1]

raw = open(capture, "rb").read()
vd_best, h_best, vd_points, h_points = float("inf"), float("inf"), 0, 0
for _ in range(rounds):
    cfg = vd.Config()
    cfg.min_range, cfg.max_range = 0.0, 1e6
    t = time.perf_counter()
    vd_points = sum(len(s.points) for s in vd.read_pcap(io.BytesIO(raw), cfg))
    vd_best = min(vd_best, time.perf_counter() - t)
    out = json.loads(subprocess.run([binary, capture, "3"], check=True, capture_output=True, text=True).stdout)
    h_points, h_best = out["points"], min(h_best, out["best_seconds"])

assert vd_points == h_points, f"point counts differ: velodyne-decoder {vd_points}, hilrig {h_points}"
vd_rate, h_rate = vd_points / vd_best, h_points / h_best
print(f"capture: {capture} ({len(raw) / 1e6:.1f} MB, {h_points} points)")
print(f"velodyne-decoder {importlib.metadata.version('velodyne-decoder')} read_pcap: {vd_rate / 1e6:8.2f} M points/s  (best of {rounds})")
print(f"hilrig decode (in-memory, 1 thread): {h_rate / 1e6:8.2f} M points/s  (best of {rounds}x3)")
print(f"ratio hilrig / velodyne-decoder: {h_rate / vd_rate:.2f}")
