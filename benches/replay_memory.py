#!/usr/bin/env python3
"""Peak memory of `hilrig replay` on a capture and a recording of at least 2 GB (issue 14, item 5).

Builds a classic pcap of SIZE_MB by repeating the frames of the bundled VLP-16 room capture
(fixtures/vlp16_room.pcapng) with advancing timestamps, records it into an MCAP with `hilrig
record --from`, and replays each with `--speed 1000000` and no destinations (every item is read,
scheduled and counted; nothing is sent) under /usr/bin/time, which reports the maximum resident
set size of the replay process. The files go in a temporary folder (on the disk of the current
directory unless TMPDIR says otherwise) and are deleted afterwards.

usage: benches/replay_memory.py [SIZE_MB]   (default 2100)
"""
import os
import re
import struct
import subprocess
import sys
import tempfile

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
size_mb = int(sys.argv[1]) if len(sys.argv) > 1 else 2100


def records(path):
    """Yield the frame bytes of every enhanced packet block of a little-endian pcapng."""
    b = open(path, "rb").read()
    off = 0
    while off + 12 <= len(b):
        kind, length = struct.unpack_from("<II", b, off)
        if kind == 6:
            caplen = struct.unpack_from("<I", b, off + 20)[0]
            yield b[off + 28:off + 28 + caplen]
        off += length


def peak(args):
    r = subprocess.run(["/usr/bin/time", "-v", *args], capture_output=True, text=True)
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr).group(1))
    wall = re.search(r"Elapsed \(wall clock\) time.*: (\S+)", r.stderr).group(1)
    return rss, wall, r.returncode, r.stderr


frames = list(records(os.path.join(root, "fixtures", "vlp16_room.pcapng")))
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")
rig = os.path.join(root, "rigs", "demo.toml")
with tempfile.TemporaryDirectory(dir=os.environ.get("TMPDIR", ".")) as tmp:
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
    mcap = os.path.join(tmp, "big.mcap")
    rss, wall, code, err = peak([exe, "record", "--rig", rig, "--from", big, "-o", mcap])
    print(f"record --from: peak RSS {rss / 1024:.1f} MB, wall {wall}, exit {code}")
    for path in (big, mcap):
        rss, wall, code, err = peak([exe, "replay", path, "--speed", "1000000"])
        items = re.search(r"replayed \d+ items \((\d+) without", err)
        print(f"replay {os.path.basename(path)} ({os.path.getsize(path) / 1e9:.2f} GB): peak RSS "
              f"{rss / 1024:.1f} MB, {items.group(1) if items else '?'} items, wall {wall}, exit {code}")
