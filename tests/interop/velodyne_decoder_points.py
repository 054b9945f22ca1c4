"""Decode a pcap with the PyPI package velodyne-decoder and write its points as raw float64.

Used by tests/velodyne_interop.rs as the independent reference decoder. Range limits are opened
(velodyne-decoder drops points below 0.1 m and above 200 m by default; hilrig keeps every
return), everything else is velodyne-decoder's default.

usage: velodyne_decoder_points.py PCAP OUT.f64 [MODEL [CALIBRATION.yml]]
OUT: one row of eight little-endian float64 per point, x, y, z, intensity, ring, return_type,
time_rel, scan, as velodyne-decoder gives them (no rounding). Binary, not CSV: numpy's savetxt
formats row by row in Python (4.1 s for 1.5 M rows of eight on the 2-core test machine, against
0.5 s for tofile), and the interop tests decode about 11 M points.
"""
import sys

import numpy as np
import velodyne_decoder as vd


def main():
    pcap, out = sys.argv[1], sys.argv[2]
    cfg = vd.Config()
    cfg.min_range = 0.0
    cfg.max_range = 1e6
    if len(sys.argv) > 3:
        cfg.model = getattr(vd.Model, sys.argv[3])
    if len(sys.argv) > 4:
        cfg.calibration = vd.Calibration.read(sys.argv[4])
    chunks = []
    for i, (stamp, pts) in enumerate(vd.read_pcap(pcap, cfg)):
        scan = np.full((len(pts), 1), i, dtype=np.float64)
        chunks.append(np.hstack([pts[:, [0, 1, 2, 3, 6, 7, 4]].astype(np.float64), scan]))
    allp = np.vstack(chunks) if chunks else np.zeros((0, 8))
    allp.astype("<f8").tofile(out)
    print(len(allp))


if __name__ == "__main__":
    main()
