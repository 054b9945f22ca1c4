#!/usr/bin/env python3
"""Replay pacing at real sensor packet rates (issue 7, item 5): a capture of SECONDS at the
VLP-16's packet rate (one packet per 1327.104 us, single return) and one at the VLS-128's
(one per 160 us, about 6250 packets/s) are replayed to a local UDP receiver; hilrig reports the
lag of every send against its deadline (p50, p99, max).

usage: benches/replay_pacing.py [SECONDS]   (default 10)
"""
import os
import re
import socket
import struct
import subprocess
import sys
import tempfile
import threading

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")


def frame(payload):
    """Ethernet/IPv4/UDP frame to port 2368 (checksums left zero)."""
    udp = struct.pack(">HHHH", 2368, 2368, 8 + len(payload), 0) + payload
    ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, 17, 0, bytes([192, 168, 1, 201]), bytes([255, 255, 255, 255]))
    return b"\xff" * 6 + b"\x60\x76\x88\x00\x00\x00" + b"\x08\x00" + ip + udp


def capture(path, period_us):
    n = int(seconds * 1e6 / period_us)
    payload = bytearray(1206)
    for b in range(12):
        payload[b * 100:b * 100 + 2] = b"\xff\xee"
    payload[1204:1206] = b"\x37\x22"
    with open(path, "wb") as f:
        f.write(struct.pack("<IHHiIII", 0xA1B23C4D, 2, 4, 0, 0, 65535, 1))
        t = 1_700_000_000 * 1_000_000_000
        for k in range(n):
            struct.pack_into("<I", payload, 1200, int(k * period_us) % 3_600_000_000)
            fr = frame(bytes(payload))
            ns = t + int(k * period_us * 1000)
            f.write(struct.pack("<IIII", ns // 1_000_000_000, ns % 1_000_000_000, len(fr), len(fr)))
            f.write(fr)
    return n


with tempfile.TemporaryDirectory() as tmp:
    for name, period in (("VLP-16 (754 packets/s)", 1327.104), ("VLS-128 (6250 packets/s)", 160.0)):
        path = os.path.join(tmp, "pace.pcap")
        n = capture(path, period)
        rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        rx.bind(("127.0.0.1", 0))
        rx.settimeout(1.0)
        got = [0]

        def drain():
            while True:
                try:
                    rx.recv(2048)
                    got[0] += 1
                except socket.timeout:
                    return

        t = threading.Thread(target=drain)
        t.start()
        r = subprocess.run([exe, "replay", path, "--lidar-to", f"127.0.0.1:{rx.getsockname()[1]}"], capture_output=True, text=True, check=True)
        t.join()
        m = re.search(r"lag p50 ([\d.]+) us, p99 ([\d.]+) us, max ([\d.]+) us", r.stderr)
        print(f"{name}: {n} packets sent over {seconds:.0f} s, {got[0]} received; lag p50 {m.group(1)} us, p99 {m.group(2)} us, max {m.group(3)} us")
