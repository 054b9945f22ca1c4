#!/usr/bin/env python3
"""Campaign scaling (issue 31, must-hold 6): a synthesized campaign of many drives on the local
executor with 1 and 2 jobs (the speed-up), and on a local Ray cluster of two worker nodes (the
overhead per task against the local executor, in milliseconds).

The drives are repetitions of the parking drive (`hilrig synth`, seeds that the fixtures do not
use); the campaign records, checks, re-simulates with the idealized model and compares each one,
validates them as one scenario, and writes the tables. Each configuration runs into a fresh
output directory; wall time, the sum of the tasks' own times (from their logs' stamps: the
campaign's per-task lines) and the overhead per task are printed.

Heavy (tens of minutes for 40 drives): a bench, not a test.

  .venv/bin/python benches/campaign_scaling.py [--drives 40] [--work DIR] [--no-ray] [--no-build]

The Ray runs need `ray` in this Python (tests/interop/requirements.txt installs it).
"""

import argparse
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HILRIG = os.path.join(ROOT, "target", "release", "hilrig")
PARKING = os.path.join(ROOT, "fixtures", "parking")


def sh(args, **kw):
    return subprocess.run(args, check=True, **kw)


def synthesize(work, drives):
    out = os.path.join(work, "drives")
    if os.path.isdir(os.path.join(out, f"rep-{drives:02d}")):
        return out
    sh([HILRIG, "synth", "--scene", os.path.join(PARKING, "scene.toml"),
        "--drive", os.path.join(PARKING, "drive.toml"),
        "--truth", os.path.join(PARKING, "truth.toml"),
        "--reps", str(drives), "--seed", "9100", "-o", out], stderr=subprocess.DEVNULL)
    return out


def campaign_file(work, drives_dir):
    path = os.path.join(work, "campaign.toml")
    with open(path, "w") as f:
        f.write(f'''name = "scaling"
steps = ["record", "check", "resim", "compare", "validate", "tables"]
rig = "{os.path.join(ROOT, 'rigs', 'demo.toml')}"

[[drive]]
recordings = "{drives_dir}/rep-*/drive.pcapng"
scene = "{{dir}}/scene.toml"

[[model]]
name = "idealized"
file = "{os.path.join(PARKING, 'idealized.toml')}"
''')
    return path


def task_seconds(stdout):
    """The tasks' own wall times from the local executor's lines (`ran  ID (3.2 s, exit 0)`)."""
    return [float(m) for m in re.findall(r"^ran\s+\S+ \(([0-9.]+) s", stdout, re.M)]


def local(campaign, out, jobs):
    shutil.rmtree(out, ignore_errors=True)
    t = time.time()
    p = subprocess.run([HILRIG, "campaign", campaign, "--out", out, "--jobs", str(jobs)],
                       capture_output=True, text=True)
    wall = time.time() - t
    if p.returncode not in (0, 1):
        sys.exit(f"campaign failed: {p.stdout[-2000:]}{p.stderr[-2000:]}")
    return wall, task_seconds(p.stdout)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def on_ray(campaign, out, work):
    ray = os.path.join(os.path.dirname(sys.executable), "ray")
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")
    port = free_port()
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    sh([ray, "start", "--head", "--port", str(port), "--num-cpus", "0", "--include-dashboard", "false",
        "--temp-dir", temp, "--disable-usage-stats"], env=env, capture_output=True)
    try:
        for _ in range(2):
            sh([ray, "start", "--address", f"127.0.0.1:{port}", "--num-cpus", "1"], env=env,
               capture_output=True)
        shutil.rmtree(out, ignore_errors=True)
        plan = os.path.join(work, "plan.json")
        with open(plan, "w") as f:
            sh([HILRIG, "campaign", "plan", campaign, "--out", out, "--json"], stdout=f)
        t = time.time()
        p = subprocess.run([sys.executable, "-m", "hilrig_ray", plan, "--address", f"127.0.0.1:{port}",
                            "--hilrig", HILRIG], cwd=os.path.join(ROOT, "python"), env=env,
                           capture_output=True, text=True)
        wall = time.time() - t
        if p.returncode not in (0, 1):
            sys.exit(f"ray campaign failed: {p.stdout[-2000:]}{p.stderr[-2000:]}")
        return wall
    finally:
        # Only this cluster's processes (its temp dir is in their command lines).
        for pid in os.listdir("/proc"):
            if pid.isdigit():
                try:
                    with open(f"/proc/{pid}/cmdline", "rb") as f:
                        if temp.encode() in f.read():
                            os.kill(int(pid), 9)
                except (OSError, ProcessLookupError):
                    pass
        shutil.rmtree(temp, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", type=int, default=40)
    ap.add_argument("--work", default=None)
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--no-build", action="store_true")
    a = ap.parse_args()
    if not a.no_build:
        sh(["cargo", "build", "--release", "--quiet"], cwd=ROOT)
    work = a.work or tempfile.mkdtemp(prefix="hilrig-scaling-")
    os.makedirs(work, exist_ok=True)
    drives = synthesize(work, a.drives)
    campaign = campaign_file(work, drives)
    plan = json.loads(subprocess.run([HILRIG, "campaign", "plan", campaign, "--json"],
                                     capture_output=True, text=True, check=True).stdout)
    n = len(plan["tasks"])
    print(f"{a.drives} drives, {n} tasks ({os.cpu_count()} cores)")
    w1, t1 = local(campaign, os.path.join(work, "out-1"), 1)
    print(f"local, 1 job:  {w1:7.1f} s wall; tasks' own time {sum(t1):7.1f} s; "
          f"overhead {1000 * (w1 - sum(t1)) / n:6.1f} ms per task")
    w2, t2 = local(campaign, os.path.join(work, "out-2"), 2)
    print(f"local, 2 jobs: {w2:7.1f} s wall; speed-up over 1 job {w1 / w2:.2f}x")
    if not a.no_ray:
        wr = on_ray(campaign, os.path.join(work, "out-ray"), work)
        print(f"Ray, 2 worker nodes of 1 CPU: {wr:7.1f} s wall; against the local executor with 2 jobs "
              f"{wr / w2:.2f}x, {1000 * (wr - w2) / n:+.1f} ms per task")
    if not a.work:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
