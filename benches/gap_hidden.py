#!/usr/bin/env python3
"""The gap workflow on drives with hidden effects (issue 15, items 1-4): the table of the closing note.

For each case, three drives of fixtures/gap/drive.toml through fixtures/parking/scene.toml are
synthesized (`hilrig synth`, with the drive's reference errors: RTK noise, GNSS latency and
jitter, lidar clock jitter, CAN noise, survey error) with a truth model = the idealized model plus
the hidden effect(s) at parameters drawn at random (seeded) from the ranges below; each capture
is recorded (`hilrig record --from`), two runs fit and one validates, and `hilrig gap` starts
from the idealized model (for motion_distortion: the idealized model with motion_distortion
disabled, a frame-based simulator) without being told what was hidden. The script prints, per
case, what was hidden, what was found in which order, the fitted values against the truth and
the validation metrics before and after.

Ranges (documented realistic values, see src/sim/model.rs): range bias ±(2-10) cm; range noise
1-5 cm; random dropout 2-20 %; detection threshold: range at 10 % reflectivity 15-40 m (it must
bite within the scene's 2-40 m); beam divergence 2-6 mrad horizontal, half that vertical (5 sub-
rays per axis); time offset ±(5-50) ms; mount misalignment ±(0.2-2)° about one axis; weather:
extinction 0.004-0.03 /m and clutter 0.5-5 % per firing, with a detection threshold (35 m at 10 %
reflectivity) that truth and start model share.

Other drives than the default: `--speed M/S` sets the cruise speed (default 6 m/s, the drive's
own), `--standing` starts the drive from standstill instead of at cruise speed, `--rpm` and
`--return-mode` set the lidar's spin (default 600) and return mode (default strongest); the
effects and the workflow stay the same (for the blind test's point: not only the drive the code
was built on).

usage: benches/gap_hidden.py [--hilrig PATH] [--work DIR] [--seed N] [--speed M/S] [--standing]
                             [--rpm N] [--return-mode strongest|last|dual] [--multi] [CASE ...]
  CASE: a name of CASES below (default: all), e.g. range_bias null-1 bias+dropout
  --multi: the cases with two or three hidden effects (issue 33, must-hold 2). The last columns
  judge each hidden effect (found, the fitted value's error against the truth, whether its 95 %
  interval holds the truth) and each kept round (did its trial make a validation metric worse
  beyond noise: a trade-off); the last line counts them over the cases.
"""
import argparse
import hashlib
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(root, "fixtures/parking/scene.toml")
DRIVE = os.path.join(root, "fixtures/gap/drive.toml")
RIG = os.path.join(root, "rigs/demo.toml")


def draw(rng, effect):
    """The hidden effect's TOML table and its true parameters."""
    sign = lambda: rng.choice([-1.0, 1.0])
    if effect == "range_bias":
        p = {"bias_m": sign() * rng.uniform(0.02, 0.10)}
    elif effect == "range_noise":
        p = {"sigma_m": rng.uniform(0.01, 0.05)}
    elif effect == "random_dropout":
        p = {"probability": rng.uniform(0.02, 0.20)}
    elif effect == "detection_threshold":
        p = {"reference_range_m": rng.uniform(15.0, 40.0), "reference_reflectivity": 0.10}
    elif effect == "beam_divergence":
        h = rng.uniform(2.0, 6.0)
        p = {"horizontal_mrad": h, "vertical_mrad": h / 2, "sub_rays_per_axis": 5}
    elif effect == "time_offset":
        p = {"offset_ms": sign() * rng.uniform(5.0, 50.0)}
    elif effect.startswith("mount_"):
        axis = effect.split("_")[1]
        p = {"roll_deg": 0.0, "pitch_deg": 0.0, "yaw_deg": 0.0}
        p[axis + "_deg"] = sign() * rng.uniform(0.2, 2.0)
        effect = "mount_misalignment"
    elif effect == "motion_distortion":
        p = {"enabled": True}
    elif effect == "weather":
        p = {"extinction_per_m": rng.uniform(0.004, 0.03), "clutter_probability": rng.uniform(0.005, 0.05)}
    else:
        raise SystemExit(f"unknown effect {effect}")
    return effect, p


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def model_toml(name, effects):
    out = [f'name = "{name}"']
    for e, p in effects:
        out.append("\n[[effect]]")
        out.append(f'name = "{e}"')
        out.extend(f"{k} = {toml_value(v)}" for k, v in p.items())
    return "\n".join(out) + "\n"


# The sensor's detection threshold, known to the start model of the weather case (extinction acts
# only through it).
THRESHOLD = ("detection_threshold", {"reference_range_m": 35.0, "reference_reflectivity": 0.1})

# name: (hidden effects, start model has motion distortion disabled)
CASES = {
    "weather": (["weather"], False),
    "range_bias": (["range_bias"], False),
    "range_noise": (["range_noise"], False),
    "random_dropout": (["random_dropout"], False),
    "detection_threshold": (["detection_threshold"], False),
    "beam_divergence": (["beam_divergence"], False),
    "motion_distortion": (["motion_distortion"], True),
    "time_offset": (["time_offset"], False),
    "mount_yaw": (["mount_yaw"], False),
    "mount_pitch": (["mount_pitch"], False),
    "mount_roll": (["mount_roll"], False),
    "null-1": ([], False),
    "null-2": ([], False),
    "null-3": ([], False),
    "bias+dropout": (["range_bias", "random_dropout"], False),
    "time_offset+noise": (["time_offset", "range_noise"], False),
    # Two and three effects at once (issue 33, must-hold 2): look-alikes together (a threshold
    # and dropout both remove returns; noise and divergence both spread ranges at edges).
    "threshold+dropout": (["detection_threshold", "random_dropout"], False),
    "noise+divergence": (["range_noise", "beam_divergence"], False),
    "yaw+noise": (["mount_yaw", "range_noise"], False),
    "bias+noise+dropout": (["range_bias", "range_noise", "random_dropout"], False),
    "threshold+dropout+noise": (["detection_threshold", "random_dropout", "range_noise"], False),
}

# Multi-effect cases, for --multi.
MULTI = [n for n, (e, _) in CASES.items() if len(e) >= 2]


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.stderr.write(r.stdout + r.stderr)
        raise SystemExit(f"failed ({r.returncode}): {' '.join(cmd)}")
    return r


def drive_file(work, speed, standing, rpm=None, return_mode=None):
    """The gap drive at another cruise speed, start, spin rate or return mode, or the drive itself."""
    if speed is None and not standing and rpm is None and return_mode is None:
        return DRIVE
    text = open(DRIVE).read().replace('rig = "../../rigs/demo.toml"', f'rig = "{RIG}"')
    if speed is not None:
        text = text.replace("cruise_speed_mps = 6.0", f"cruise_speed_mps = {speed}")
        text = text.replace("start_speed_mps = 6.0", f"start_speed_mps = {speed}")
    if rpm is not None:
        text = text.replace("rpm = 600", f"rpm = {rpm}")
    if return_mode is not None:
        text = text.replace('return_mode = "strongest"', f'return_mode = "{return_mode}"')
    if standing:
        text = text.replace("start_speed_mps = 6.0\n", "").replace(f"start_speed_mps = {speed}\n", "")
    path = os.path.join(work, "drive.toml")
    open(path, "w").write(text)
    return path


def synth_seed(name, seed):
    """The synthesis seed of case `name` at bench seed `seed`: a hash of both, so that no two
    (case, seed) pairs share their noise (a sum of the name's characters and the seed made
    null-1 at seed 2 the same drives as null-2 at seed 1)."""
    return int.from_bytes(hashlib.sha256(f"{name}/{seed}".encode()).digest()[:4], "big")


def case(hilrig, work, name, seed, drive=DRIVE):
    effects, frame_based = CASES[name]
    rng = random.Random(f"{name}-{seed}")
    hidden = [draw(rng, e) for e in effects]
    known = [THRESHOLD] if name == "weather" else []
    d = os.path.join(work, name)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    truth = os.path.join(d, "truth.toml")
    open(truth, "w").write(model_toml(f"hidden {name}", known + hidden))
    start = os.path.join(d, "start.toml")
    open(start, "w").write(
        model_toml("idealized", known + ([("motion_distortion", {"enabled": False})] if frame_based else []))
    )
    run([hilrig, "synth", "--scene", SCENE, "--drive", drive, "--truth", truth, "--reps", "3",
         "--seed", str(synth_seed(name, seed)), "-o", d])
    study = [f'model = "start.toml"']
    for i in (1, 2, 3):
        rep = os.path.join(d, f"rep-{i:02}")
        run([hilrig, "record", "--rig", RIG, "--from", os.path.join(rep, "drive.pcapng"),
             "-o", os.path.join(d, f"run-{i}.mcap")])
        study += ["[[run]]", f'recording = "run-{i}.mcap"', f'scene = "rep-{i:02}/scene.toml"',
                  f'role = "{"validate" if i == 3 else "fit"}"']
    open(os.path.join(d, "study.toml"), "w").write("\n".join(study) + "\n")
    r = run([hilrig, "gap", os.path.join(d, "study.toml"), "-o", os.path.join(d, "out"),
             "--no-detection-limits"])
    report = json.load(open(os.path.join(d, "out", "gap.json")))
    return hidden, report, r.stdout


# The parameter each effect is judged by: (its name in gap.json, its name in the truth).
MAIN = {
    "range_bias": "bias_m", "range_noise": "sigma_m", "random_dropout": "probability",
    "detection_threshold": "reference_range_m", "beam_divergence": "horizontal_mrad",
    "time_offset": "offset_ms", "weather": "extinction_per_m",
}


# The tolerance each fitted main parameter is judged by: 20 %, and 30 % for the horizontal
# beam divergence, which shows only at the sides of objects and whose 95 % intervals on these
# drives span about ±30 % (README, the gap workflow's intervals; issue 33 asks 30 % of divergence from
# another footprint model too).
TOLERANCE = {"beam_divergence": 0.3}


def limits_of(hilrig, d):
    """The detection limits of case directory `d`'s study: `hilrig gap` run again with them (the
    cases run without, to save their time), by effect name."""
    run([hilrig, "gap", os.path.join(d, "study.toml"), "-o", os.path.join(d, "out-limits")])
    report = json.load(open(os.path.join(d, "out-limits", "gap.json")))
    return {lim["effect"]: lim for lim in report.get("limits") or []}


def judge(hidden, report, tally, limits=lambda: {}):
    """Per hidden effect: found, the fitted main parameter's error against the truth, and whether
    its 95 % interval holds the truth; and the kept rounds whose trial made a metric worse. An
    effect not found is set against its detection limit (`limits`, asked only then): missed
    below the limit the runs could show, or missed although the runs could have shown it."""
    out = []
    for e, p in hidden:
        tally["hidden"] += 1
        if e == "mount_misalignment":
            key = next(k for k, v in p.items() if v != 0.0)
        elif e == "motion_distortion":
            key = None
        else:
            key = MAIN[e]
        rd = next((r for r in report["rounds"] if r["chosen"] == e), None)
        if rd is None:
            lim = limits().get(e)
            seen = lim and lim.get("seen_at")
            if key is None or seen is None:
                out.append(f"{e}: not found (no limit)")
            elif (abs(p[key]) >= seen) != bool(lim.get("at_most")):
                out.append(f"{e}: not found, although above its limit {seen:.3g}")
            else:
                tally["below_limit"] += 1
                out.append(f"{e}: not found, below its limit {seen:.3g} (truth {abs(p[key]):.3g})")
            continue
        tally["found"] += 1
        if key is None:
            out.append(f"{e}: found")
            tally["within"] += 1
            continue
        # The value in the final model: the round's, or a later round's re-fit of it (fitted
        # again with the effects added after it).
        params = rd["parameters"]
        for later in report["rounds"]:
            if later["round"] > rd["round"] and later["chosen"]:
                for rf in later.get("refits") or []:
                    if rf["effect"] == e:
                        params = rf["after"]
        par = next(x for x in params if x["name"] == key)
        truth, got = p[key], par["value"]
        err = (got - truth) / abs(truth)
        tally["within"] += abs(err) <= TOLERANCE.get(e, 0.2)
        inside = ""
        if par.get("interval"):
            lo, hi = par["interval"]
            tally["intervals"] += 1
            tally["covered"] += lo <= truth <= hi
            inside = "in" if lo <= truth <= hi else "out"
        out.append(f"{e} {key}: {err:+.0%} {inside}")
    worse = []
    for rd in report["rounds"]:
        if not rd["chosen"]:
            continue
        t = [t for t in rd["trials"] if t["kept"] and t["effect"] == rd["chosen"]][-1]
        m = t.get("metrics")
        if m and m.get("worse"):
            tally["worse"] += 1
            worse.append(f'round {rd["round"]} {rd["chosen"]}: {m["decision"]}, {len(m["worse"])} worse')
    return "; ".join(out), "; ".join(worse)


def fmt_params(p):
    return ", ".join(f"{k} {v:.4g}" for k, v in p.items()
                     if k not in ("reference_reflectivity", "sub_rays_per_axis", "enabled")
                     and not (k.endswith("_deg") and v == 0.0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hilrig", default=None,
                    help="the binary to test (default: this tree's, rebuilt with cargo build --release)")
    ap.add_argument("--work", default=None)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--speed", type=float, default=None)
    ap.add_argument("--standing", action="store_true")
    ap.add_argument("--rpm", type=int, default=None)
    ap.add_argument("--return-mode", choices=["strongest", "last", "dual"], default=None)
    ap.add_argument("--multi", action="store_true", help="the cases with two or three effects")
    ap.add_argument("cases", nargs="*")
    a = ap.parse_args()
    if a.hilrig is None:
        # Never measure a stale binary: build this tree first.
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
        a.hilrig = os.path.join(root, "target/release/hilrig")
    names = a.cases or (MULTI if a.multi else list(CASES))
    work = a.work or tempfile.mkdtemp(prefix="gap-hidden-")
    os.makedirs(work, exist_ok=True)
    drive = drive_file(work, a.speed, a.standing, a.rpm, a.return_mode)
    print(f"work: {work}; drive: {a.speed or 6.0} m/s, {'from standstill' if a.standing else 'moving at the start'}"
          f", lidar {a.rpm or 600} rpm, {a.return_mode or 'strongest'} return")
    print("| case | hidden (truth) | found, in order (fitted) | validation log-likelihood per 1000 firings | validation metrics before -> after | per hidden effect: found, error, truth in 95 % interval | kept rounds with a metric worse |")
    print("|---|---|---|---|---|---|---|")
    tally = {"hidden": 0, "found": 0, "below_limit": 0, "within": 0, "intervals": 0, "covered": 0,
             "worse": 0}
    for n in names:
        hidden, report, _ = case(a.hilrig, work, n, a.seed, drive)
        cache = {}

        def limits(n=n):
            if "l" not in cache:
                cache["l"] = limits_of(a.hilrig, os.path.join(work, n))
            return cache["l"]

        checks, worse = judge(hidden, report, tally, limits)
        found = []
        ll = ""
        ocr = ""
        for rd in report["rounds"]:
            if rd["chosen"]:
                ps = {p["name"]: p["value"] for p in rd["parameters"]}
                found.append(f'{rd["chosen"]} ({fmt_params(ps)})')
                t = [t for t in rd["trials"] if t["kept"] and t["effect"] == rd["chosen"]][-1]
                ll += f'{t["before"]["log_likelihood_per_1000"]:.1f} -> {t["after"]["log_likelihood_per_1000"]:.1f}; '
                b, f = rd.get("metrics_before"), rd.get("metrics_after")
                if b and f and b.get("ocr") is not None and f.get("ocr") is not None:
                    avm = lambda m: {a["metric"]: a["avm"] for a in m["avm"]}.get("returns_per_scan")
                    ocr += (f'OCR {b["ocr"]:.3f} -> {f["ocr"]:.3f}, precision {b["precision"]:.3f} -> {f["precision"]:.3f}, '
                            f'AVM returns/scan {avm(b):.0f} -> {avm(f):.0f}; ')
        truth = "; ".join(f"{e} ({fmt_params(p)})" for e, p in hidden) or "nothing (reference noise only)"
        print(f"| {n} | {truth} | {'; '.join(found) or 'nothing'} | {ll or '-'} | {ocr or '-'} | {checks or '-'} | {worse or 'none'} |", flush=True)
    print(f"hidden effects: {tally['hidden']}, found {tally['found']}, not found below their detection limit "
          f"{tally['below_limit']}, fitted within their tolerance (20 %; divergence 30 %) {tally['within']}; "
          f"fitted parameters with an interval {tally['intervals']}, truth inside {tally['covered']}; "
          f"kept rounds that made a validation metric worse: {tally['worse']}")


if __name__ == "__main__":
    main()
