#!/usr/bin/env python3
"""The gap workflow's false alarms (issue 33, must-hold 1): null studies, in which the drives are
synthesized with the idealized model itself (nothing hidden: only the drive's reference errors,
RTK noise, GNSS latency and jitter, lidar clock jitter, CAN noise and survey error), so that every
effect the workflow adds is a false alarm.

Each study is three drives (two fit, one validates), as in benches/gap_hidden.py. The studies
take turns between three drives: the two bundled ones through the parking scene,
fixtures/gap/drive.toml (town speed with a bend, started moving) at cruise speeds spread over
2-12 m/s and fixtures/parking/drive.toml (the parking manoeuvre from standstill, with the
walker) at 1.5-4 m/s; and a second scene layout, fixtures/street/ (a residential street between
rows of houses, parked cars, lamp posts and trees) at 2-12 m/s. Each study's synthesis seed is a hash of its drive, speed and index
(gap_hidden.synth_seed), so no two studies share their noise.

The workflow runs with --no-full-metrics: the decision then rests on the likelihood alone, and
the keep rule's metric half, which can only refuse an effect, is left out; the count is an upper
bound on the false alarms of the full workflow. The script prints one line per study and the
count of studies that added any effect.

usage: benches/gap_null.py [--hilrig PATH] [--work DIR] [--studies N] [--first K] [--seeds]
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import tempfile

import gap_hidden as gh

PARKING_DRIVE = os.path.join(gh.root, "fixtures/parking/drive.toml")
STREET_SCENE = os.path.join(gh.root, "fixtures/street/scene.toml")
STREET_DRIVE = os.path.join(gh.root, "fixtures/street/drive.toml")
DRIVES = ("gap", "parking", "street")
# Cruise speeds each drive is swept over, m/s (the parking manoeuvre is a slow one).
SPEEDS = {"gap": (2.0, 12.0), "parking": (1.5, 4.0), "street": (2.0, 12.0)}


def drive_at(work, which, speed):
    """The drive `which` (of DRIVES) at cruise speed `speed`, written into `work`."""
    src = {"gap": gh.DRIVE, "parking": PARKING_DRIVE, "street": STREET_DRIVE}[which]
    text = open(src).read().replace('rig = "../../rigs/demo.toml"', f'rig = "{gh.RIG}"')
    for key in ("cruise_speed_mps", "start_speed_mps"):
        text = re.sub(rf"^{key} = [0-9.]+", f"{key} = {speed}", text, flags=re.M)
    path = os.path.join(work, "drive.toml")
    open(path, "w").write(text)
    return path


def plan(n):
    """The studies: (index, drive, speed, synthesis seed)."""
    out = []
    for k in range(n):
        which = DRIVES[k % len(DRIVES)]
        j, m = k // len(DRIVES), max((n + len(DRIVES) - 1) // len(DRIVES) - 1, 1)
        lo, hi = SPEEDS[which]
        speed = round(lo + (hi - lo) * j / m, 2)
        out.append((k, which, speed, gh.synth_seed(f"null/{which}/{speed}", k)))
    return out


def study(hilrig, work, k, which, speed, seed):
    d = os.path.join(work, f"null-{k:02}")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    drive = drive_at(d, which, speed)
    truth = os.path.join(d, "truth.toml")
    open(truth, "w").write('name = "idealized"\n')
    shutil.copy(truth, os.path.join(d, "start.toml"))
    scene = STREET_SCENE if which == "street" else gh.SCENE
    gh.run([hilrig, "synth", "--scene", scene, "--drive", drive, "--truth", truth, "--reps", "3",
            "--seed", str(seed), "-o", d])
    lines = ['model = "start.toml"']
    for i in (1, 2, 3):
        rep = os.path.join(d, f"rep-{i:02}")
        gh.run([hilrig, "record", "--rig", gh.RIG, "--from", os.path.join(rep, "drive.pcapng"),
                "-o", os.path.join(d, f"run-{i}.mcap")])
        lines += ["[[run]]", f'recording = "run-{i}.mcap"', f'scene = "rep-{i:02}/scene.toml"',
                  f'role = "{"validate" if i == 3 else "fit"}"']
    open(os.path.join(d, "study.toml"), "w").write("\n".join(lines) + "\n")
    r = subprocess.run([hilrig, "gap", os.path.join(d, "study.toml"), "-o", os.path.join(d, "out"),
                        "--no-full-metrics", "--no-detection-limits"], capture_output=True, text=True)
    if r.returncode != 0:
        return None, r.stderr.strip().splitlines()[-1] if r.stderr.strip() else f"exit {r.returncode}"
    report = json.load(open(os.path.join(d, "out", "gap.json")))
    added = [rd["chosen"] for rd in report["rounds"] if rd["chosen"]]
    return added, report.get("ended") or ""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hilrig", default=None)
    ap.add_argument("--work", default=None)
    ap.add_argument("--studies", type=int, default=30)
    ap.add_argument("--first", type=int, default=0, help="start at this study (resume)")
    ap.add_argument("--seeds", action="store_true",
                    help="print the synthesis seed of every study and of benches/gap_hidden.py's cases at bench seeds 1-20, one per line, and exit")
    a = ap.parse_args()
    if a.seeds:
        for k, which, speed, seed in plan(a.studies):
            print(f"null {k} {which} {speed} {seed}")
        for name in gh.CASES:
            for s in range(1, 21):
                print(f"hidden {name} {s} {gh.synth_seed(name, s)}")
        return
    if a.hilrig is None:
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=gh.root, check=True)
        a.hilrig = os.path.join(gh.root, "target/release/hilrig")
    work = a.work or tempfile.mkdtemp(prefix="gap-null-")
    os.makedirs(work, exist_ok=True)
    print(f"work: {work}")
    print("| study | drive | speed m/s | seed | added |")
    print("|---|---|---|---|---|")
    alarms, ran, refused = 0, 0, 0
    for k, which, speed, seed in plan(a.studies)[a.first:]:
        added, why = study(a.hilrig, work, k, which, speed, seed)
        if added is None:
            refused += 1
            print(f"| {k} | {which} | {speed} | {seed} | not run: {why} |", flush=True)
            continue
        ran += 1
        alarms += bool(added)
        print(f"| {k} | {which} | {speed} | {seed} | {', '.join(added) or 'nothing'} |", flush=True)
    print(f"null studies that added an effect: {alarms} of {ran} run ({refused} refused by the workflow)")


if __name__ == "__main__":
    main()
