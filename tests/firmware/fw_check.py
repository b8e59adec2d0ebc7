#!/usr/bin/python3
"""Compare the firmware's own evaluations (EVAL lines printed over
semihosting, raw Q24) with what it2nd serves over Modbus TCP after the
firmware's upload: FC23 writes q_u, q_w (x10000, registers 64..65) and reads
the float32 results (128..235) in one transaction; every float32 must be
bit-identical to the firmware's Q24 value converted to float32 (it2nd
converts with (float)((double)v / 2^24), docs/registers.md).
usage: fw_check.py PORT QEMU_LOG UNIT"""
import os
import struct
import sys

from pymodbus.client import ModbusTcpClient

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

R = report.Report("fw_check")
port, log, unit = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
evals = []
with open(log, errors="replace") as f:
    for line in f:
        if line.startswith("EVAL "):
            evals.append([int(x) for x in line.split()[1:]])
if not evals:
    sys.exit(R.verdict(["no EVAL lines in %s" % log], ""))

c = ModbusTcpClient("127.0.0.1", port=port)
assert c.connect(), "connect"
st = c.read_input_registers(0, 26, slave=unit).registers
if st[1] != 2 or st[21] != 0:
    sys.exit(R.verdict(["model state %d (want 2 solved), word order %d" % (st[1], st[21])], ""))

def f32_bits(x):
    return struct.unpack(">I", struct.pack(">f", x))[0]

fails, compared = [], 0
for e in evals:
    ku, kw, oor, vals = e[0], e[1], e[2], e[3:]
    assert len(vals) == 42 + 12, "EVAL line length"
    rr = c.readwrite_registers(read_address=128, read_count=108, write_address=64,
                               write_registers=[ku, kw], unit=unit, slave=unit)  # 3.0.0: unit
    if rr.isError():
        fails.append("FC23 at (%d, %d): %s" % (ku, kw, rr))
        continue
    regs = rr.registers
    qs = c.read_holding_registers(84, 2, slave=unit).registers
    if (qs[0] << 16 | qs[1]) != oor:
        fails.append("(%d,%d) out_of_range %#x != %#x" % (ku, kw, qs[0] << 16 | qs[1], oor))
    for k, raw in enumerate(vals):
        got = regs[2 * k] << 16 | regs[2 * k + 1]
        want = f32_bits(raw / float(1 << 24))
        compared += 1
        if got != want:
            fails.append("(%d,%d) value %d: modbus %08x firmware %08x (raw %d)" % (ku, kw, k, got, want, raw))
c.close()
sys.exit(R.verdict(fails, "%d points, %d float32 values compared, each bit-identical" % (len(evals), compared)))
