#!/usr/bin/env python3
"""Re-simulation speed for a VLP-32C as a multiple of real time (issue 5, item 6: at least 5x on
this 2-core machine), end to end: `hilrig resim` reading the recording, casting every firing of
every recorded packet, and writing the simulated scans and clouds.

The parking drive is synthesized with the demo rig's VLP-32C variant, recorded with `hilrig record
--from`, and re-simulated with the idealized model and with the parking truth model (beam
divergence: 9 rays per firing). Best of three runs each.

usage: benches/resim_speed.py [MODE]   (MODE: strongest or dual; default both)
"""
import os
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
modes = sys.argv[1:] or ["strongest", "dual"]
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")

with tempfile.TemporaryDirectory() as d:
    rig = open(os.path.join(root, "rigs/demo.toml")).read().replace(
        'model = "vlp16"', 'model = "vlp32c"').replace(
        'dbc = "hilrig-ego.dbc"', f'dbc = "{os.path.join(root, "rigs/hilrig-ego.dbc")}"')
    rig_path = os.path.join(d, "vlp32c.toml")
    open(rig_path, "w").write(rig)
    for mode in modes:
        drive = open(os.path.join(root, "fixtures/parking/drive.toml")).read().replace(
            'rig = "../../rigs/demo.toml"', f'rig = "{rig_path}"').replace(
            'return_mode = "strongest"', f'return_mode = "{mode}"')
        drive_path = os.path.join(d, f"drive-{mode}.toml")
        open(drive_path, "w").write(drive)
        out = os.path.join(d, mode)
        subprocess.run([exe, "synth", "--scene", os.path.join(root, "fixtures/parking/scene.toml"),
                        "--drive", drive_path, "--truth",
                        os.path.join(root, "fixtures/parking/idealized.toml"),
                        "--reps", "1", "--seed", "1", "-o", out],
                       check=True, stderr=subprocess.DEVNULL)
        run = os.path.join(d, f"run-{mode}.mcap")
        subprocess.run([exe, "record", "--rig", rig_path, "--from",
                        os.path.join(out, "rep-01/drive.pcapng"), "-o", run],
                       check=True, stderr=subprocess.DEVNULL)
        duration = float(open(os.path.join(out, "rep-01/truth.toml")).read()
                         .split("duration_s = ")[1].split("\n")[0])
        for model in ["idealized", "truth"]:
            best = None
            for _ in range(3):
                t = time.time()
                subprocess.run([exe, "resim", run, "--scene", os.path.join(out, "rep-01/scene.toml"),
                                "--model", os.path.join(root, f"fixtures/parking/{model}.toml"),
                                "-o", os.path.join(d, "sim.mcap"), "--rig", rig_path],
                               check=True, stderr=subprocess.DEVNULL)
                el = time.time() - t
                best = el if best is None else min(best, el)
            print(f"VLP-32C {mode}, {model} model: {duration:.1f} s of drive re-simulated in "
                  f"{best:.2f} s = {duration / best:.1f}x real time ({os.cpu_count()} cores)")
