#!/usr/bin/env python3
"""GNSS and CAN decoding throughput: hilrig against pynmea2 and cantools, same input, same run
(issue 3, item 7). Run with the test venv's python (it has pynmea2 and cantools).

GNSS: the ZED-F9R log (NMEA + UBX + RTCM3) repeated to ~8 MB. hilrig frames and decodes
everything (checksums, NMEA, UBX, epochs); pynmea2 is given only the NMEA lines (it cannot read
UBX or RTCM3) and parses each with checksum checking: the peer's work is the smaller one.
CAN: 200,000 frames of the VW MQB DBC (every message, random payloads); cantools decodes each
with scaling, hilrig decodes each into physical values.

usage: benches/compare_gnss_can.py [DATA_DIR]   (default $HILRIG_REAL_DATA or ../shared/data)
"""
import json
import os
import random
import subprocess
import sys
import tempfile
import time

import cantools
import pynmea2

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
data = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HILRIG_REAL_DATA", os.path.join(root, "..", "shared", "data"))
sys.path.insert(0, os.path.join(root, "tests", "interop"))
import cantools_decode  # noqa: E402  (the DBC clean-up cantools needs)

out = subprocess.run(["cargo", "bench", "--bench", "gnss_can_throughput", "--no-run", "--message-format=json", "--quiet"],
                     cwd=root, check=True, capture_output=True, text=True).stdout
binary = [json.loads(l)["executable"] for l in out.splitlines() if l.startswith("{") and "gnss_can_throughput" in l and json.loads(l).get("executable")][-1]

log = os.path.join(data, "gnss", "ublox-zed-f9r.log")
raw = open(log, "rb").read()
copies = max(1, 8_000_000 // len(raw))
lines = raw.split(b"\n")
nmea = [l.strip().decode("ascii", "replace") for l in lines if l.startswith(b"$")] * copies
best_py = float("inf")
for _ in range(3):
    t = time.perf_counter()
    ok = 0
    for s in nmea:
        try:
            pynmea2.parse(s, check=True)
            ok += 1
        except pynmea2.ParseError:
            pass
    best_py = min(best_py, time.perf_counter() - t)
nmea_bytes = sum(len(s) + 2 for s in nmea)
h = json.loads(subprocess.run([binary, "gnss", log, "10"], check=True, capture_output=True, text=True).stdout)
print(f"GNSS log: {log} x{copies} ({h['bytes'] / 1e6:.1f} MB, {len(nmea)} NMEA sentences)")
print(f"  pynmea2 {pynmea2.version if hasattr(pynmea2, 'version') else ''} (NMEA lines only): {nmea_bytes / best_py / 1e6:8.2f} MB/s of NMEA, {len(nmea) / best_py:10.0f} sentences/s")
print(f"  hilrig (whole mixed stream):        {h['mb_per_second']:8.2f} MB/s")
print(f"  ratio hilrig / pynmea2 (MB/s):      {h['mb_per_second'] / (nmea_bytes / best_py / 1e6):.1f}")

dbc_path = os.path.join(data, "can", "vw_mqb.dbc")
db = cantools.database.load_string(cantools_decode.cleaned(open(dbc_path, encoding="cp1252").read()), database_format="dbc", strict=False)
rng = random.Random(7)
msgs = [m for m in db.messages if not m.is_extended_frame and m.length <= 8]
frames = []
for _ in range(200_000):
    m = rng.choice(msgs)
    frames.append((m, bytes(rng.getrandbits(8) for _ in range(m.length))))
with tempfile.NamedTemporaryFile("w", suffix=".jsonl", delete=False) as f:
    for m, d in frames:
        f.write(json.dumps({"id": m.frame_id, "extended": False, "data": d.hex()}) + "\n")
    frames_path = f.name
best_ct, decoded = float("inf"), 0
for _ in range(2):
    t = time.perf_counter()
    decoded = 0
    for m, d in frames:
        try:
            m.decode(d, decode_choices=False, scaling=True, allow_truncated=True)
            decoded += 1
        except cantools.database.errors.DecodeError:
            pass
    best_ct = min(best_ct, time.perf_counter() - t)
h = json.loads(subprocess.run([binary, "can", dbc_path, frames_path, "10"], check=True, capture_output=True, text=True).stdout)
os.unlink(frames_path)
print(f"CAN: {len(frames)} frames of {dbc_path}")
print(f"  cantools {cantools.__version__}: {len(frames) / best_ct:12.0f} frames/s ({decoded} decoded)")
print(f"  hilrig:        {h['frames_per_second']:12.0f} frames/s")
print(f"  ratio hilrig / cantools: {h['frames_per_second'] / (len(frames) / best_ct):.0f}")
