#!/usr/bin/python3
"""Third-party client check: pymodbus (Debian python3-pymodbus) reads it2nd
exactly as docs/registers.md describes, and the values match the CLI's
`it2n eval` for the same data.
usage: pymodbus_client.py HOST PORT IT2N_CLI DATA.csv"""
import os
import struct
import subprocess
import sys

from pymodbus.client import ModbusTcpClient

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

R = report.Report("pymodbus")
host, port, cli, csv = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
c = ModbusTcpClient(host, port=port)
if not R.check(c.connect(), "connect to %s:%d" % (host, port)):
    sys.exit(R.finish())

# Status block, FC04 (3xxxx), unit 1.
st = c.read_input_registers(0, 26, slave=1).registers
R.check(st[0] == 1, "map version 1", st[0])
R.check(st[1] == 2, "state solved", st[1])
R.check(st[21] == 0, "default word order ABCD", st[21])
scale = st[22]

def f32(regs, k):  # ABCD: first register holds the high word
    return struct.unpack(">f", struct.pack(">HH", regs[k], regs[k + 1]))[0]

for u, w in ((0.25, 0.5), (0.0, 1.0), (0.7, 0.3)):
    bad = []
    # FC23: write q_u, q_w (x10000) at 64, read the float32 results at 128.
    # (pymodbus 3.0.0rc1 takes the unit id of this request as `unit`.)
    rr = c.readwrite_registers(read_address=128, read_count=108, write_address=64,
                               write_registers=[round(u * 10000), round(w * 10000)], unit=1, slave=1)
    res = rr.registers
    sc = c.read_holding_registers(256, 84, slave=1).registers
    out = subprocess.run([cli, "eval", csv, "--at", "%g,%g" % (u, w), "--decimals", "9"],
                         check=True, capture_output=True, text=True).stdout.splitlines()[1:]
    for fp, line in enumerate(out):
        f = line.split(",")
        want = [float(f[3]), float(f[4]), 0.0, float(f[5]), float(f[6]), float(f[7])]
        for ch in range(6):
            got = f32(res, (fp * 6 + ch) * 2)
            if abs(got - want[ch]) > 1e-6 * max(1.0, abs(want[ch])):
                bad.append("fp %d ch %d: %r != %r" % (fp, ch, got, want[ch]))
        for k in range(3):
            got = struct.unpack(">h", struct.pack(">H", sc[fp * 9 + 6 + k]))[0]
            if abs(got - want[3 + k] * 10000) > 0.5 + 1e-6:
                bad.append("scaled fp %d k %d: %d vs %f" % (fp, k, got, want[3 + k]))
        x = struct.unpack(">i", struct.pack(">HH", sc[fp * 9], sc[fp * 9 + 1]))[0]
        if abs(x - want[0] * scale) > 0.5 + 1e-6:
            bad.append("scaled x fp %d: %d vs %f" % (fp, x, want[0] * scale))
    R.check(len(out) == 7 and not bad, "(%g,%g): float32 and scaled results equal it2n eval for %d footprints"
            % (u, w, len(out)), "; ".join(bad))
c.close()
sys.exit(R.finish())
