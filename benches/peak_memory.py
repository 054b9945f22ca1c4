#!/usr/bin/env python3
"""Peak memory of `hilrig decode` on a 1 GB capture (issue 2, item 8).

Builds a ~1 GB pcap by repeating the packets of a capture (default: the bundled VLP-16 room
fixture, whose packets are rewrapped into classic pcap with advancing timestamps), then runs
`hilrig decode --format summary` and `--format csv -o /dev/null` under /usr/bin/time and reports
the maximum resident set size. The capture goes in a temporary folder and is deleted afterwards.

usage: benches/peak_memory.py [SIZE_MB]
"""
import os
import re
import struct
import subprocess
import sys
import tempfile

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
size_mb = int(sys.argv[1]) if len(sys.argv) > 1 else 1024


def records(path):
    """Yield (frame bytes) of every enhanced packet block of a little-endian pcapng."""
    b = open(path, "rb").read()
    off = 0
    while off + 12 <= len(b):
        kind, length = struct.unpack_from("<II", b, off)
        if kind == 6:
            caplen = struct.unpack_from("<I", b, off + 20)[0]
            yield b[off + 28:off + 28 + caplen]
        off += length


frames = list(records(os.path.join(root, "fixtures", "vlp16_room.pcapng")))
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")
with tempfile.TemporaryDirectory() as tmp:
    big = os.path.join(tmp, "big.pcap")
    with open(big, "wb") as f:
        f.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1))
        t = 1_700_000_000 * 1_000_000
        written = 0
        while written < size_mb * 1_000_000:
            for fr in frames:
                f.write(struct.pack("<IIII", t // 1_000_000, t % 1_000_000, len(fr), len(fr)))
                f.write(fr)
                t += 1327
                written += 16 + len(fr)
    print(f"capture: {os.path.getsize(big) / 1e9:.2f} GB")
    for args in (["--format", "summary"], ["--format", "csv", "-o", "/dev/null"]):
        r = subprocess.run(["/usr/bin/time", "-v", exe, "decode", big, "--model", "vlp16", *args],
                           capture_output=True, text=True)
        rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr).group(1))
        wall = re.search(r"Elapsed \(wall clock\) time.*: (\S+)", r.stderr).group(1)
        points = re.search(r"points: (\d+)", r.stderr).group(1)
        print(f"hilrig decode {' '.join(args):32s} peak RSS {rss / 1024:7.1f} MB, {points} points, wall {wall}, exit {r.returncode}")
