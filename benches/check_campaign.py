#!/usr/bin/env python3
"""`hilrig check` over many synthesized parking drives (issue 12's campaigns): clean drives with
different seeds and cruise speeds, and each `[faults]` kind with several seeds at a size above
its limit. For every drive: the faults raised, and for the estimated quantities whether the
2-sigma interval the check reports contains the injected truth. Prints one line per drive and a
summary: false faults on clean drives, detection rate and interval coverage per fault kind.

Then the lever-arm grid: the true antenna at 0.0, 0.4, 0.8 and 1.2 m ahead of the rear axle, the
rig file given to `check` saying 0.0, 0.3, 0.6 or 1.0 m: the estimate must be within 10 cm of the
truth, or the check must say it cannot determine it.

usage: python3 benches/check_campaign.py [CLEAN_DRIVES] [SEEDS_PER_FAULT]   (default 10 3)
"""
import json
import os
import subprocess
import sys
import tempfile

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
n_clean = int(sys.argv[1]) if len(sys.argv) > 1 else 10
n_fault = int(sys.argv[2]) if len(sys.argv) > 2 else 3
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")
base = open(os.path.join(root, "fixtures/parking/drive.toml")).read().replace(
    'rig = "../../rigs/demo.toml"', f'rig = "{os.path.join(root, "rigs/demo.toml")}"')
CAN_LATENCY_MS = 1.0
# name, [faults] lines, fault expected, (estimate key, sigma key, truth) or None
FAULTS = [
    ("rtk_float", 'rtk = [{ from_s = 8.0, to_s = 12.0, quality = 5 }]', "rtk_float", None),
    ("sigma_spike", 'sigma_spike = [{ from_s = 6.0, to_s = 7.0, sigma_m = 0.05 }]', "sigma_spike", None),
    ("gnss_time_offset", "gnss_time_offset_ms = 30.0", "gnss_time_offset",
     ("gnss_time_offset_ms", "gnss_time_offset_sigma_ms", 30.0 - CAN_LATENCY_MS)),
    ("lidar_free_running", "lidar_free_running = { offset_ms = 5.0, drift_ppm = 300.0 }",
     "lidar_not_pps_locked", None),
    ("lidar_gap", "lidar_gap = [{ from_s = 5.0, to_s = 6.0 }]", "lidar_gap", None),
    ("can_speed_scale", "can_speed_scale = 1.03", "can_speed_scale",
     ("can_speed_scale", "can_speed_scale_sigma", 1.03)),
    ("antenna", "antenna_error_m = [0.4, 0.0, 0.0]", "lever_arm",
     ("lever_arm_x_measured_m", "lever_arm_x_sigma_m", 1.0)),
]


def drive(tmp, name, faults, seed, speed=2.2, rig_antenna_x=None):
    text = base.replace("cruise_speed_mps = 2.2", f"cruise_speed_mps = {speed}")
    d = os.path.join(tmp, name)
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "drive.toml")
    open(path, "w").write(text + ("\n[faults]\n" + faults + "\n" if faults else ""))
    subprocess.run([exe, "synth", "--scene", os.path.join(root, "fixtures/parking/scene.toml"),
                    "--drive", path, "--truth", os.path.join(root, "fixtures/parking/idealized.toml"),
                    "--reps", "1", "--seed", str(seed), "-o", d], check=True,
                   stderr=subprocess.DEVNULL)
    run = os.path.join(d, "run.mcap")
    subprocess.run([exe, "record", "--rig", os.path.join(root, "rigs/demo.toml"), "--from",
                    os.path.join(d, "rep-01/drive.pcapng"), "-o", run], check=True,
                   stderr=subprocess.DEVNULL)
    return check(d, run, rig_antenna_x)


def check(d, run, rig_antenna_x=None):
    out = os.path.join(d, "check.json")
    extra = []
    if rig_antenna_x is not None:
        rig = open(os.path.join(root, "rigs/demo.toml")).read().replace(
            "antenna = { x = 0.60,", f"antenna = {{ x = {rig_antenna_x:.2f},").replace(
            'dbc = "hilrig-ego.dbc"', f'dbc = "{os.path.join(root, "rigs/hilrig-ego.dbc")}"')
        path = os.path.join(d, f"rig-{rig_antenna_x}.toml")
        open(path, "w").write(rig)
        extra = ["--rig", path]
    subprocess.run([exe, "check", run, "--scene", os.path.join(d, "rep-01/scene.toml"),
                    "--json", out] + extra, stdout=subprocess.DEVNULL)
    return json.load(open(out))


def covered(v, est):
    key, sk, truth = est
    e, s = v["spatial"].get(key), v["spatial"].get(sk)
    return e is not None and s is not None and abs(e - truth) <= 2 * s


with tempfile.TemporaryDirectory() as tmp:
    false = 0
    truths = [("can_speed_scale", "can_speed_scale_sigma", 1.0),
              ("gnss_time_offset_ms", "gnss_time_offset_sigma_ms", -CAN_LATENCY_MS),
              ("lever_arm_x_measured_m", "lever_arm_x_sigma_m", 0.60)]
    cover = {t[0]: 0 for t in truths}
    for k in range(n_clean):
        speed = 1.6 + 0.2 * (k % 5)
        v = drive(tmp, f"clean{k}", "", 100 + k, speed)
        names = [f["name"] for f in v["faults"]]
        false += bool(names)
        for t in truths:
            cover[t[0]] += covered(v, t)
        print(f"clean seed {100 + k} at {speed:.1f} m/s: faults {names}, warnings "
              f"{[w['name'] for w in v['warnings']]}")
    print(f"clean: {false} of {n_clean} drives with a fault; 2-sigma intervals containing the "
          f"truth: " + ", ".join(f"{k} {c}/{n_clean}" for k, c in cover.items()))
    for name, lines, expected, est in FAULTS:
        found = inside = 0
        for s in range(n_fault):
            v = drive(tmp, f"{name}{s}", lines, 200 + s)
            names = [f["name"] for f in v["faults"]]
            found += expected in names
            if est:
                inside += covered(v, est)
            print(f"{name} seed {200 + s}: faults {names}")
        extra = f", interval contains the truth {inside}/{n_fault}" if est else ""
        print(f"{name}: detected {found}/{n_fault}{extra}")
    ok = total = 0
    for true_x in [0.0, 0.4, 0.8, 1.2]:
        name = f"lever{true_x}"
        drive(tmp, name, f"antenna_error_m = [{true_x - 0.6:.2f}, 0.0, 0.0]", 300)
        d = os.path.join(tmp, name)
        for prior in [0.0, 0.3, 0.6, 1.0]:
            v = check(d, os.path.join(d, "run.mcap"), prior)
            sp = v["spatial"]
            est, sig = sp.get("lever_arm_x_measured_m"), sp.get("lever_arm_x_sigma_m")
            undecided = est is None or any(w["name"] == "lever_arm" and "not determinable" in
                                           w["detail"] for w in v["warnings"])
            good = (est is not None and abs(est - true_x) <= 0.10) or (est is None and undecided)
            ok += good
            total += 1
            print(f"antenna {true_x:.1f} m, rig says {prior:.1f} m: estimate "
                  f"{'n/a' if est is None else f'{est:.3f} ± {sig:.3f}'} m"
                  f"{' (not determinable)' if undecided else ''}")
    print(f"lever arm: {ok}/{total} within 10 cm of the truth or reported not determinable")
