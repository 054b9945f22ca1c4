#!/usr/bin/env python3
"""The live recorder under load (issue 4, item 5): VLP-16 data packets over loopback UDP on a
schedule of RATE packets/s and NMEA at 20 Hz through a pty for SECONDS; then SIGINT. Prints the
rate the sender reached, the packets and sentences in the file (read with the PyPI `mcap` reader
of tests/interop), the recorder's drop count and its peak RSS. The test suite checks the same
claim (nothing lost, nothing dropped) on a short burst; this is the sustained figure.

usage: .venv/bin/python benches/record_load.py [RATE] [SECONDS]   (default 20000 30)
"""
import json
import os
import pty
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
rate = float(sys.argv[1]) if len(sys.argv) > 1 else 20000.0
seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 30.0
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")


def payloads(path):
    b = open(path, "rb").read()
    off, out = 0, []
    while off + 12 <= len(b):
        kind, length = struct.unpack_from("<II", b, off)
        if kind == 6:
            caplen = struct.unpack_from("<I", b, off + 20)[0]
            udp = b[off + 28:off + 28 + caplen][14 + 20:]
            if len(udp) - 8 == 1206:
                out.append(bytearray(udp[8:]))
        off += length
    return out


def nmea(body):
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"${body}*{c:02X}\r\n".encode()


def peak_rss_mb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return 0.0


pkts = payloads(os.path.join(root, "fixtures", "vlp16_room.pcapng"))
with tempfile.TemporaryDirectory() as tmp:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    master, slave = pty.openpty()
    tty = os.ttyname(slave)
    rig = os.path.join(tmp, "rig.toml")
    open(rig, "w").write(f'name = "load"\n[lidar]\nmodel = "vlp16"\nbind = "127.0.0.1"\n'
                         f'data_port = {port}\nposition_port = {port + 1}\n'
                         f'[gnss]\nport = "{tty}"\nbaud = 115200\n')
    out = os.path.join(tmp, "load.mcap")
    proc = subprocess.Popen([exe, "record", "--rig", rig, "-o", out], stderr=subprocess.PIPE)
    while not os.path.exists(out + ".active"):
        time.sleep(0.02)
    time.sleep(0.3)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n = sentences = 0
    peak = 0.0
    t0 = time.perf_counter()
    next_nmea = t0
    while time.perf_counter() - t0 < seconds:
        p = pkts[n % len(pkts)]
        struct.pack_into("<I", p, 1200, (1_000_000 + n * 50) % 3_600_000_000)
        tx.sendto(p, ("127.0.0.1", port))
        n += 1
        now = time.perf_counter()
        if now >= next_nmea:
            k = sentences
            os.write(master, nmea(f"GNGGA,12{k // 1200 % 60:02}{k // 20 % 60:02}.{k % 20 * 5:02},"
                                  "4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042"))
            sentences += 1
            next_nmea += 0.05
            if sentences % 20 == 0:
                peak = max(peak, peak_rss_mb(proc.pid))
        due = t0 + n / rate
        while time.perf_counter() < due:
            pass
    wall = time.perf_counter() - t0
    time.sleep(0.5)
    peak = max(peak, peak_rss_mb(proc.pid))
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate()
    py = os.path.join(root, ".venv", "bin", "python")
    v = json.loads(subprocess.run([py, os.path.join(root, "tests/interop/mcap_read.py"), out,
                                   "--count-scan-packets"], check=True,
                                  capture_output=True).stdout)
    in_file = v["scan_packets"]
    nmea_in_file = v["channels"]["/gnss/nmea"]["count"]
    dropped = v["metadata"]["hilrig/end"]["lidar_dropped"]
    print(f"sent {n} packets in {wall:.1f} s ({n / wall:.0f} packets/s against a schedule of "
          f"{rate:.0f}) and {sentences} sentences")
    print(f"file: {in_file} packets ({n - in_file} lost), {nmea_in_file} sentences "
          f"({sentences - nmea_in_file} lost); recorder dropped {dropped}; exit {proc.returncode}; "
          f"peak RSS {peak:.1f} MB")
