#!/usr/bin/env python3
"""How long `hilrig check` takes on a long drive, as a share of the drive's duration (issue 6,
item 4: less than 5 %).

A drive of about MINUTES minutes (default 10) is synthesized with `hilrig synth` on the parking
scene (a serpentine at 8 km/h with the full VLP-16 stream, RTK GNSS at 10 Hz and CAN at 50 Hz,
the idealized lidar model), recorded with `hilrig record --from`, then checked; the check's wall
time is measured around the process (best of three, to ride out a noisy shared machine).

usage: benches/check_duration.py [MINUTES]
"""
import math
import os
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
minutes = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")

# A serpentine inside the parking scene's 120 m ground: legs of 100 m, 6 m apart, joined by half
# circles of 3 m (a car turns on that; `synth` refuses a path tighter than a car can turn), with
# waypoints every 2.5 m along the legs and every 45 degrees around the turns (2.3 m apart: a
# Catmull-Rom spline through corners or unevenly spaced waypoints loops).
speed = 2.2
leg_m = 100 + math.pi * 3
legs = max(1, int(minutes * 60 * speed / leg_m) + 1)
if legs > 16:
    sys.exit(f"at most {16 * leg_m / speed / 60:.0f} minutes of serpentine fit the scene")
way = []
for i in range(legs):
    y = -45.0 + 6 * i
    xs = [-50.0 + 2.5 * k for k in range(41)]
    way += [[x, y] for x in (xs if i % 2 == 0 else xs[::-1])]
    if i + 1 < legs:
        side = 1 if i % 2 == 0 else -1
        for a in (-45, 0, 45):
            r = math.radians(a)
            way.append([round(50.0 * side + side * 3 * math.cos(r), 3), round(y + 3 + 3 * math.sin(r), 3)])

with tempfile.TemporaryDirectory() as d:
    drive = os.path.join(d, "drive.toml")
    with open(drive, "w") as f:
        f.write(f'''name = "long serpentine"
start_utc = "2026-11-21T12:00:00Z"
rig = "{os.path.join(root, 'rigs', 'demo.toml')}"
[path]
waypoints = {way}
cruise_speed_mps = {speed}
''')
    t = time.time()
    subprocess.run([exe, "synth", "--scene", os.path.join(root, "fixtures/parking/scene.toml"),
                    "--drive", drive, "--truth", os.path.join(root, "fixtures/parking/idealized.toml"),
                    "--reps", "1", "--seed", "1", "-o", os.path.join(d, "out")],
                   check=True, stderr=subprocess.DEVNULL)
    print(f"synthesized in {time.time() - t:.0f} s")
    mcap = os.path.join(d, "run.mcap")
    t = time.time()
    subprocess.run([exe, "record", "--rig", os.path.join(root, "rigs/demo.toml"), "--from",
                    os.path.join(d, "out/rep-01/drive.pcapng"), "-o", mcap],
                   check=True, stderr=subprocess.DEVNULL)
    print(f"recorded in {time.time() - t:.0f} s ({os.path.getsize(mcap) / 1e6:.0f} MB)")
    best = None
    for _ in range(3):
        t = time.time()
        r = subprocess.run([exe, "check", mcap, "--json", os.path.join(d, "c.json")],
                           capture_output=True, text=True)
        el = time.time() - t
        best = el if best is None else min(best, el)
    import json
    rep = json.load(open(os.path.join(d, "c.json")))
    dur = rep["duration_s"]
    print(r.stdout.splitlines()[0], f"(exit {r.returncode})")
    print(f"drive {dur:.0f} s ({dur / 60:.1f} min); check {best:.2f} s = {100 * best / dur:.2f} % "
          f"of the drive's duration (limit 5 %)")
