#!/usr/bin/env python3
"""`hilrig check` on clean drives that are not the parking drive: longer, faster, other shapes.

`benches/check_campaign.py` varies the parking drive (seeds, speeds, starts). This one keeps the
parking scene and its stream errors (RTK 1 cm Gauss-Markov 2 s, CAN 1 cm/s and 2 mrad/s, GNSS
latency 35 ms) but drives other paths without the pedestrian: a loop of about 250 m, a 160 m
straight and a slalom, at 3 to 12 m/s, standing or already moving at the start. Per drive: the
verdict and faults (there must be none), the warnings, the heading error of the smoothed
trajectory against the synthesizer's truth (95th percentile over the usable segments), and each
estimate against its truth in units of its own sigma (GNSS time offset: -1 ms, the CAN frames'
latency; CAN speed scale: 1; antenna x: 0.60 m, the rig's). Over all drives: the faults, the worst
heading, and how often the 2-sigma interval holds the truth.

usage: python3 benches/check_other_drives.py [SEEDS_PER_CASE]   (default 3)
"""
import bisect
import concurrent.futures
import csv
import datetime
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")
base = open(os.path.join(root, "fixtures/parking/drive.toml")).read().replace(
    'rig = "../../rigs/demo.toml"', f'rig = "{os.path.join(root, "rigs/demo.toml")}"')
# No pedestrian, no yield: these drives do not stop for anyone.
base = re.sub(r"\[\[walker\]\].*?(?=\[variation\])", "", base, flags=re.S)
base = base.replace("acceleration_mps2 = 0.8", "acceleration_mps2 = 1.5")
PATHS = {
    "loop": "[[-60.0, 0.0], [-20.0, 0.0], [10.0, -5.0], [30.0, 10.0], [35.0, 35.0], "
            "[15.0, 50.0], [-20.0, 45.0], [-45.0, 30.0]]",
    "straight": "[[-80.0, 0.0], [80.0, 0.0]]",
    "slalom": "[[-60.0, 0.0], [-40.0, 6.0], [-20.0, -6.0], [0.0, 6.0], [20.0, -6.0], [40.0, 6.0]]",
}
CASES = [("loop", 3.0), ("loop", 5.0), ("loop", 8.0), ("straight", 12.0), ("slalom", 6.0)]
TRUTH = [("gnss_time_offset_ms", "gnss_time_offset_sigma_ms", -1.0),
         ("can_speed_scale", "can_speed_scale_sigma", 1.0),
         ("lever_arm_x_measured_m", "lever_arm_x_sigma_m", 0.60)]
tmp = tempfile.mkdtemp()


def one(job):
    name, speed, seed, start = job
    text = re.sub(r"waypoints = \[.*\]\n", f"waypoints = {PATHS[name]}\n", base)
    text = text.replace("cruise_speed_mps = 2.2", f"cruise_speed_mps = {speed}")
    if start == "moving":
        text = text.replace("lead_in_s = 0.8", f"lead_in_s = 0.8\nstart_speed_mps = {speed}")
    d = os.path.join(tmp, f"{name}-{speed}-{seed}-{start}")
    os.makedirs(d)
    open(os.path.join(d, "drive.toml"), "w").write(text)
    subprocess.run([exe, "synth", "--scene", os.path.join(root, "fixtures/parking/scene.toml"),
                    "--drive", os.path.join(d, "drive.toml"),
                    "--truth", os.path.join(root, "fixtures/parking/idealized.toml"),
                    "--reps", "1", "--seed", str(seed), "-o", d],
                   check=True, capture_output=True)
    run = os.path.join(d, "run.mcap")
    subprocess.run([exe, "record", "--rig", os.path.join(root, "rigs/demo.toml"), "--from",
                    os.path.join(d, "rep-01/drive.pcapng"), "-o", run],
                   check=True, capture_output=True)
    out = os.path.join(d, "check.json")
    subprocess.run([exe, "check", run, "--scene", os.path.join(d, "rep-01/scene.toml"),
                    "--json", out, "--trajectory", os.path.join(d, "trajectory.csv")],
                   capture_output=True)
    v = json.load(open(out))
    truth = [(float(r["t"]), float(r["yaw_deg"]))
             for r in csv.DictReader(open(os.path.join(d, "rep-01/truth.csv")))]
    tt = [t for t, _ in truth]
    run_start = datetime.datetime.fromisoformat(v["start"].replace("Z", "+00:00")).timestamp()
    segs = [(s["from_s"], s["to_s"]) for s in v["segments"] if s["verdict"] == "pass"]
    errors = []
    for r in csv.DictReader(open(os.path.join(d, "trajectory.csv"))):
        t = float(r["t"])
        i = bisect.bisect_left(tt, t)
        if i <= 0 or i >= len(tt):
            continue
        (ta, ya), (tb, yb) = truth[i - 1], truth[i]
        yaw = ya + (t - ta) / (tb - ta) * ((yb - ya + 180) % 360 - 180)
        if any(a <= t - run_start <= b for a, b in segs):
            errors.append(abs((float(r["yaw_deg"]) - yaw + 180) % 360 - 180))
    errors.sort()
    p95 = errors[int(0.95 * len(errors))] if errors else float("nan")
    z = {}
    for key, sigma_key, true in TRUTH:
        e, s = v["spatial"].get(key), v["spatial"].get(sigma_key)
        if isinstance(e, (int, float)) and isinstance(s, (int, float)) and s > 0:
            z[key] = (e - true) / s
    shutil.rmtree(d, True)
    return job, v, truth[-1][0] - truth[0][0], p95, z


jobs = [(name, speed, seed, start) for name, speed in CASES
        for seed in range(1, seeds + 1) for start in ("standing", "moving")]
faulty, worst, zs = 0, 0.0, {k: [] for k, _, _ in TRUTH}
try:
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        for (name, speed, seed, start), v, duration, p95, z in pool.map(one, jobs):
            faults = [f["name"] for f in v["faults"]]
            faulty += bool(faults)
            worst = max(worst, p95)
            for k, x in z.items():
                zs[k].append(x)
            print(f"{name} {speed:.0f} m/s seed {seed} {start}: {v['verdict']}, faults {faults}, "
                  f"warnings {[w['name'] for w in v.get('warnings', [])]}, {duration:.0f} s, "
                  f"heading p95 {p95:.3f} deg, "
                  + ", ".join(f"{k} z {x:+.2f}" for k, x in z.items()), flush=True)
finally:
    shutil.rmtree(tmp, True)
print(f"{len(jobs)} drives: {faulty} with a fault; worst heading p95 {worst:.3f} deg")
for k, xs in zs.items():
    if xs:
        rms = math.sqrt(sum(x * x for x in xs) / len(xs))
        inside = sum(abs(x) <= 2 for x in xs)
        print(f"  {k}: 2-sigma interval holds the truth {inside}/{len(xs)}, "
              f"mean z {sum(xs) / len(xs):+.2f}, rms z {rms:.2f}")
