#!/usr/bin/env python3
"""CPU share of one core used by `hilrig record` while a VLP-32C streams at its real rate
(issue 4, item 7). The packets of the bundled VLP-32C dual-return fixture are sent over loopback
UDP at the sensor's pace (one packet per 331.776 us: 3014 packets/s in dual return) for
SECONDS, and the recorder's user+system CPU time is read from /proc before and after.

usage: benches/record_cpu.py [SECONDS]   (default 20)
"""
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "hilrig")


def payloads(path):
    b = open(path, "rb").read()
    off, out = 0, []
    while off + 12 <= len(b):
        kind, length = struct.unpack_from("<II", b, off)
        if kind == 6:
            caplen = struct.unpack_from("<I", b, off + 20)[0]
            frame = b[off + 28:off + 28 + caplen]
            udp = frame[14 + 20:]
            if len(udp) - 8 == 1206:
                out.append(bytearray(udp[8:]))
        off += length
    return out


def cpu_ticks(pid):
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])  # utime + stime


pkts = payloads(os.path.join(root, "fixtures", "vlp32c_dual_room.pcapng"))
with tempfile.TemporaryDirectory() as tmp:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    rig = os.path.join(tmp, "rig.toml")
    open(rig, "w").write(f'name = "cpu"\n[lidar]\nmodel = "vlp32c"\nbind = "127.0.0.1"\ndata_port = {port}\nposition_port = {port + 1}\n')
    out = os.path.join(tmp, "cpu.mcap")
    proc = subprocess.Popen([exe, "record", "--rig", rig, "-o", out], stderr=subprocess.DEVNULL)
    while not os.path.exists(out + ".active"):
        time.sleep(0.02)
    time.sleep(0.3)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    hz = os.sysconf("SC_CLK_TCK")
    c0, t0 = cpu_ticks(proc.pid), time.perf_counter()
    period = 331.776e-6
    n = 0
    while time.perf_counter() - t0 < seconds:
        p = pkts[n % len(pkts)]
        struct.pack_into("<I", p, 1200, (n * 332) % 3_600_000_000)
        tx.sendto(p, ("127.0.0.1", port))
        n += 1
        due = t0 + n * period
        while time.perf_counter() < due:
            pass
    wall = time.perf_counter() - t0
    c1 = cpu_ticks(proc.pid)
    proc.send_signal(signal.SIGINT)
    proc.wait()
    share = (c1 - c0) / hz / wall
    print(f"sent {n} packets in {wall:.1f} s ({n / wall:.0f} packets/s, VLP-32C dual return)")
    print(f"hilrig record CPU: {(c1 - c0) / hz:.2f} s in {wall:.1f} s = {100 * share:.1f} % of one core")
