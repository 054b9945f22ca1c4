#!/usr/bin/env python3
"""Fig. 5 of Rosenberger et al. 2019 on the five parking repetitions (issue 13): each capture
recorded, re-simulated with the idealized model, compared at the paper's 10 cm cell (below the
admissible cell: --allow-small-cell) and at the admissible cell: Spearman's rho of OCR against
the mean distance to the objects, with its bootstrap interval. Then the same at 10 cm with the
reference errors taken out (the true scene, whose objects carry no survey error, and the
synthesizer's true trajectory), to show which error dominates the surveyed case.

usage: python3 benches/parking_fig5.py
"""
import json
import os
import subprocess
import tempfile

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")
fx = os.path.join(root, "fixtures", "parking")


def run(*args):
    subprocess.run([exe, *args], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def compare(run_mcap, sim, scene, out, *extra):
    run("compare", run_mcap, sim, "--scene", scene, "--json", out, *extra)
    s = json.load(open(out))
    r = s["summary"]["ocr_vs_distance"]
    return s, (f"rho {r['rho']:+.2f} [{r['low']:+.2f}, {r['high']:+.2f}]" if r else "n/a")


with tempfile.TemporaryDirectory() as tmp:
    for rep in range(1, 6):
        d = os.path.join(fx, f"rep-{rep:02}")
        m = os.path.join(tmp, f"run{rep}.mcap")
        run("record", "--rig", os.path.join(root, "rigs/demo.toml"), "--from",
            os.path.join(d, "drive.pcapng.zst"), "-o", m)
        sim = os.path.join(tmp, f"sim{rep}.mcap")
        run("resim", m, "--scene", os.path.join(d, "scene.toml"), "--model",
            os.path.join(fx, "idealized.toml"), "-o", sim)
        s10, r10 = compare(m, sim, os.path.join(d, "scene.toml"), os.path.join(tmp, "a.json"),
                           "--cell", "0.1", "--allow-small-cell")
        sad, rad = compare(m, sim, os.path.join(d, "scene.toml"), os.path.join(tmp, "b.json"))
        truth = os.path.join(d, "truth.csv")
        simt = os.path.join(tmp, f"simt{rep}.mcap")
        run("resim", m, "--scene", os.path.join(fx, "scene.toml"), "--model",
            os.path.join(fx, "idealized.toml"), "--trajectory", truth, "-o", simt)
        st, rt = compare(m, simt, os.path.join(fx, "scene.toml"), os.path.join(tmp, "c.json"),
                         "--cell", "0.1", "--allow-small-cell", "--trajectory", truth)
        print(f"rep {rep}: 10 cm: OCR {s10['summary']['ocr_mean']:.3f}, {r10}; admissible "
              f"{sad['cell_m']:.2f} m: OCR {sad['summary']['ocr_mean']:.3f}, {rad}; 10 cm in the "
              f"true scene on the true trajectory: OCR {st['summary']['ocr_mean']:.3f}, {rt}")
