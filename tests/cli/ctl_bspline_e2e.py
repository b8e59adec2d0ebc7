#!/usr/bin/python3
"""ctl-bspline: a 64x64 uncertain survey (examples/survey_64x64.csv, type-2
with z) goes from CSV through 'it2nctl push --kind bspline' over Modbus TCP
into a real it2nd, is read back by a PLC (pymodbus: status, the query
registers, the paged coefficient window, a point upload) and compared bit
for bit with 'it2n --kind bspline' on the same file: the float32 registers
must hold exactly the float32 of the core's Q24 value, the scaled registers
exactly the daemon's documented rounding of it (docs/registers.md). Then
'it2nctl plot' draws it, and the model survives kill -9 (WAL replay) and a
clean restart (snapshot version 4: Q30 memberships).

usage: ctl_bspline_e2e.py IT2NCTL IT2N IT2ND"""

import logging
import os
import signal
import struct
import subprocess
import sys
import tempfile
import time
from fractions import Fraction as Fr

from pymodbus.client import ModbusTcpClient

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402
from it2ntest.proc import wait_port  # noqa: E402

logging.disable(logging.CRITICAL)  # pymodbus 3.0.0 logs about unit=

CTL, IT2N, IT2ND = (os.path.abspath(a) for a in sys.argv[1:4])
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SURVEY = os.path.join(ROOT, "examples", "survey_64x64.csv")
FPS = ["LL", "LR", "L", "D", "R", "RL", "RR"]
CHS = ["x", "y", "z", "T", "I", "F"]
COORD_SCALE = 1000
R = report.Report("ctl-bspline", quiet_ok=True)  # ~100 checks: failures only
check = R.check


def run(binary, *args, timeout=120):
    p = subprocess.run([binary, *args], capture_output=True, text=True,
                       timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def q24(text):
    """Decimal text (9 digits) to the core's Q24 integer (exact: the text
    is the Q24 value rounded to 1e-9, far below 2^-25)."""
    return round(Fr(text) * (1 << 24))


def f32_bits(q):
    """The float32 the daemon sends for Q24 value q (round to nearest)."""
    return struct.unpack(">I", struct.pack(">f", q / float(1 << 24)))[0]


def scaled(q, scale, lo, hi):
    """it2n_regmap_q24_to_scaled: round half away from zero, clamped."""
    s = q * scale
    half = 1 << 23
    v = (s + half if s >= 0 else s - half)
    v = int(Fr(v, 1 << 24))  # C division truncates toward zero
    return max(lo, min(hi, v))


def regs_u32(r, k):
    return (r[k] << 16) | r[k + 1]


def ok(resp):
    return resp is not None and not resp.isError()


def want_eval(csv, u, w):
    """it2n eval at (u, w): {fp: [q24 x 6]}."""
    rc, out, err = run(IT2N, "eval", "--kind", "bspline", csv, "--decimals",
                       "9", "--at", f"{u},{w}")
    check(rc == 0, f"it2n eval {u},{w}: {err}")
    res = {}
    for line in out.strip().split("\n")[1:]:
        f = line.split(",")
        res[f[2]] = [q24(x) for x in f[3:9]]
    return res


class Daemon:
    def __init__(self, conf, log):
        self.conf, self.log = conf, log
        self.p = None

    def start(self, port):
        self.p = subprocess.Popen([IT2ND, "-c", self.conf, "-f"],
                                  stdout=open(self.log, "a"),
                                  stderr=subprocess.STDOUT)
        return wait_port(port, self.p, timeout=10.0)

    def stop(self, sig):
        """Stop with sig; for SIGTERM the exit status must be 0 (a clean
        stop; under ASan also no error or leak report)."""
        rc = None
        if self.p and self.p.poll() is None:
            self.p.send_signal(sig)
            rc = self.p.wait(timeout=30)
            if sig == signal.SIGTERM:
                check(rc == 0, f"it2nd stopped by SIGTERM exits 0 (got {rc})")
        self.p = None
        return rc


def plc_eval(c, u16, w16):
    """A PLC's query: write q_u, q_w (x10000) and read the float32 and the
    scaled results in one FC23 each. Returns (f32 regs, scaled regs)."""
    r1 = c.readwrite_registers(read_address=128, read_count=108,
                               write_address=64, write_registers=[u16, w16],
                               unit=1)
    r2 = c.read_holding_registers(256, 84, unit=1)
    if not ok(r1) or not ok(r2):
        return None, None
    return r1.registers, r2.registers


def compare_plc(c, csv, u16, w16, label):
    """Every result register of (u16, w16) against it2n's Q24 values."""
    fr, sr = plc_eval(c, u16, w16)
    check(fr is not None, f"{label}: PLC query ({u16}, {w16}) answered")
    if fr is None:
        return
    want = want_eval(csv, f"{u16 / 10000:.4f}", f"{w16 / 10000:.4f}")
    bad = []
    for fi, fp in enumerate(FPS):
        for ci, ch in enumerate(CHS):
            got = regs_u32(fr, (fi * 6 + ci) * 2)
            if got != f32_bits(want[fp][ci]):
                bad.append(f"f32 {fp} {ch}: {got:08x} vs "
                           f"{f32_bits(want[fp][ci]):08x}")
        base = fi * 9
        for ci in range(3):
            got = regs_u32(sr, base + 2 * ci)
            got = got - (1 << 32) if got >= 1 << 31 else got
            exp = scaled(want[fp][ci], COORD_SCALE, -(1 << 31), (1 << 31) - 1)
            if got != exp:
                bad.append(f"i32 {fp} {CHS[ci]}: {got} vs {exp}")
        for k in range(3):
            got = sr[base + 6 + k]
            got = got - 65536 if got >= 32768 else got
            exp = scaled(want[fp][3 + k], 10000, -32767, 32767)
            if got != exp:
                bad.append(f"i16 {fp} {CHS[3 + k]}: {got} vs {exp}")
    check(not bad, f"{label} ({u16}, {w16}): " + "; ".join(bad[:6]))
    return fr


def main():
    tmp = tempfile.mkdtemp(prefix="ctl-bspline-")
    port = free_port()
    conf = os.path.join(tmp, "it2nd.conf")
    state = os.path.join(tmp, "state")
    with open(conf, "w") as f:
        f.write(f"[daemon]\nstate_dir = {state}\n"
                # the kill -9 below loses no page cache: fdatasync would
                # only slow the 28672 uploads (daemon-durability and
                # daemon-powercut try the disk)
                "fsync = no\n"
                f"[modbus]\ntcp_listen = 127.0.0.1:{port}\n"
                f"coord_scale = {COORD_SCALE}\n"
                "[model:1]\nkind = bspline\nn = 63\nm = 63\nz = yes\n"
                # the largest grid: storage for 256 x 256 points
                "[model:3]\nkind = bspline\nn = 255\nm = 255\n"
                "[model:2]\npreload = paper\n")
    d = Daemon(conf, os.path.join(tmp, "it2nd.log"))
    conn = ("--tcp", f"127.0.0.1:{port}")
    try:
        check(d.start(port), "it2nd starts with a kind = bspline model")
        # a Bezier-kind file pushed to the B-spline unit: refused, nothing sent
        paper = os.path.join(ROOT, "examples", "paper_4x4.csv")
        if os.path.exists(paper):
            rc, out, err = run(CTL, "push", paper, *conn)
            check(rc == 2 and "bspline model" in err,
                  f"Bezier data to a B-spline unit refused: {rc} {err}")
        t0 = time.monotonic()
        rc, out, err = run(CTL, "push", "--kind", "bspline", SURVEY, *conn)
        check(rc == 0 and "pushed 28672 points" in out and "solved" in out,
              f"push --kind bspline: {rc} {out} {err}")
        print(f"ctl-bspline: 28672 points pushed over Modbus TCP in "
              f"{time.monotonic() - t0:.1f} s")
        rc, out, err = run(CTL, "status", *conn)
        f = out.strip().split("\n")[-1].split(",")
        check(rc == 0 and f[:9] + f[10:] ==
              "1,solved,63,63,type-2,xyz,uniform,28672,28672,0,bspline"
              .split(","), f"status: {out} {err}")

        c = ModbusTcpClient("127.0.0.1", port=port)
        check(c.connect(), "PLC connects")
        st = c.read_holding_registers(0, 32, unit=1)
        check(ok(st), "status block 0..31 readable")
        r = st.registers if ok(st) else [0] * 32
        check(r[1] == 2 and r[2] == 63 and r[3] == 63 and r[4] == 1,
              f"state solved, n = m = 63, flags z: {r[:5]}")
        check(r[28] == 1 and r[29] == 66 and r[30] == 66 and r[31] == 0,
              f"kind 1, net 66 x 66: {r[28:32]}")
        check(r[5] == 28672 and r[6] == 28672, f"u16 counts: {r[5:7]}")
        cnt = c.read_holding_registers(88, 4, unit=1)
        check(ok(cnt) and regs_u32(cnt.registers, 0) == 28672 and
              regs_u32(cnt.registers, 2) == 28672, "u32 counts 28672")
        gen = regs_u32(r, 7)
        b = c.read_holding_registers(28, 4, unit=2)
        check(ok(b) and b.registers[0] == 0 and b.registers[1] == 4,
              "the Bezier unit: kind 0, net rows 4")
        big = c.read_holding_registers(0, 32, unit=3)
        cnt3 = c.read_holding_registers(88, 4, unit=3)
        check(ok(big) and big.registers[2] == 255 and big.registers[3] == 255
              and big.registers[28] == 1 and big.registers[6] == 65535 and
              ok(cnt3) and regs_u32(cnt3.registers, 2) == 256 * 256 * 7 and
              regs_u32(cnt3.registers, 0) == 0,
              "a 256 x 256 B-spline model: n = m = 255, u16 count saturated, "
              "u32 count 458752")
        ctrl = c.read_holding_registers(2048, 2, unit=1)
        check(not ok(ctrl), "control_net block: 02 for a B-spline model")
        ctrl = c.read_holding_registers(2048, 2, unit=2)
        check(ok(ctrl), "control_net block still served for the Bezier unit")

        # the PLC's queries, bit for bit: knots, between them, corners
        pts = [(0, 0), (10000, 10000), (5000, 5000), (3000, 7000),
               (1234, 9876), (9999, 1), (7937, 3175), (10000, 0)]
        before = {}
        for u16, w16 in pts:
            before[(u16, w16)] = compare_plc(c, SURVEY, u16, w16, "PLC eval")

        # the coefficient window against 'it2n solve --kind bspline'
        rc, out, err = run(IT2N, "solve", "--kind", "bspline", SURVEY,
                           "--decimals", "9")
        check(rc == 0, f"it2n solve: {err}")
        coef = {}
        for line in out.strip().split("\n")[1:]:
            f = line.split(",")
            coef[(int(f[0]), int(f[1]), f[2])] = [q24(x) for x in f[3:9]]
        bad = []
        for fp, ch, row in [(3, 3, 0), (3, 0, 33), (0, 2, 65), (6, 5, 12),
                            (1, 4, 47)]:
            wr = c.write_registers(96, [fp, ch, row], unit=1)
            check(ok(wr), f"page select ({fp}, {ch}, {row})")
            vals = []
            for start in (0, 124):
                rr = c.read_holding_registers(384 + start,
                                              min(124, 132 - start), unit=1)
                check(ok(rr), f"window read at {start}")
                vals += rr.registers if ok(rr) else []
            for s in range(66):
                got = regs_u32(vals, 2 * s) if len(vals) >= 132 else None
                exp = f32_bits(coef[(row - 1, s - 1, FPS[fp])][ch])
                if got != exp:
                    bad.append(f"({FPS[fp]},{CHS[ch]},{row},{s}): {got} vs "
                               f"{exp:08x}")
            tail = c.read_holding_registers(384 + 132, 4, unit=1)
            check(ok(tail) and tail.registers == [0, 0, 0, 0],
                  "window past net_cols reads 0")
        check(not bad, "coefficient window: " + "; ".join(bad[:5]))
        check(not ok(c.write_registers(96, [7, 0, 0], unit=1)),
              "page select fp 7: refused")
        # CONFIGURE beyond the configured storage: 03, nothing changed
        bad_cfg = c.write_registers(32, [100, 63, 1], unit=1)
        le = c.read_holding_registers(9, 1, unit=1)
        st2 = c.read_holding_registers(0, 8, unit=1)
        check(not ok(bad_cfg) and ok(le) and le.registers[0] == 65534 and
              ok(st2) and st2.registers[1] == 2 and st2.registers[2] == 63,
              "cfg n = 100 beyond n = 63: range error, model kept")

        # it2nctl eval / sample over Modbus agree with it2n (float32 view)
        rc, got, err = run(CTL, "eval", "--at", "0.3,0.7", "--at", "1,0",
                           "--decimals", "9", *conn)
        rc2, want, _ = run(IT2N, "eval", "--kind", "bspline", SURVEY,
                           "--at", "0.3,0.7", "--at", "1,0", "--decimals", "9")
        gl = got.strip().split("\n")
        wl = want.strip().split("\n")
        worst = 0.0
        for a, b in zip(gl[1:], wl[1:]):
            for x, y in zip(a.split(",")[3:9], b.split(",")[3:9]):
                fy = float(y)
                worst = max(worst, abs(float(x) - fy) / max(abs(fy), 1e-3))
        check(rc == 0 and rc2 == 0 and gl[0] == wl[0] and len(gl) == len(wl)
              and worst <= 2.0 ** -23, f"it2nctl eval: {worst} {err}")
        # locate at a data point of D: found inside, the same surface
        # values as it2n locate (float32 over Modbus)
        at = ("--at", "200.195,299.505", "--at", "150.5,320.25")
        rc, got, err = run(CTL, "locate", *at, "--decimals", "9", *conn)
        rc2, want, _ = run(IT2N, "locate", "--kind", "bspline", SURVEY, *at,
                           "--decimals", "9")
        gl, wl = got.strip().split("\n"), want.strip().split("\n")
        worst, stat = 0.0, []
        for a_, b_ in zip(gl[1:], wl[1:]):
            fa, fb = a_.split(","), b_.split(",")
            stat.append((fa[-1], fb[-1]))
            for x, y in zip(fa[5:9], fb[5:9]):
                worst = max(worst, abs(float(x) - float(y)) /
                            max(abs(float(y)), 1e-3))
        check(rc == 0 and rc2 == 0 and len(gl) == len(wl) == 15 and
              worst <= 2.0 ** -22 and
              all(a_ == ("inside" if b_ == "inside" else "outside|noconv")
                  for a_, b_ in stat) and stat[3][1] == "inside",
              f"it2nctl locate: {worst} {stat} {err}")
        rc, got, err = run(CTL, "sample", "--grid", "3x3", "--footprint",
                           "D", *conn)
        check(rc == 0 and len(got.strip().split("\n")) == 10,
              f"it2nctl sample 3x3: {rc} {err}")

        # plotted from the daemon (coefficients over the window) and from
        # the file: both images made
        png = os.path.join(tmp, "live.png")
        rc, out, err = run(CTL, "plot", "-o", png, *conn)
        check(rc == 0 and os.path.getsize(png) > 10000,
              f"it2nctl plot of the B-spline model: {rc} {err}")
        png2 = os.path.join(tmp, "file.png")
        rc, out, err = run(IT2N, "plot", "--kind", "bspline", SURVEY, "-o",
                           png2)
        check(rc == 0 and os.path.getsize(png2) > 10000,
              f"it2n plot --kind bspline: {rc} {err}")

        # a PLC replaces one point: the update is the full solve of the
        # edited file, bit for bit
        lines = open(SURVEY).read().split("\n")
        edited = os.path.join(tmp, "edited.csv")
        hdr = [k for k, ln in enumerate(lines) if ln.startswith("i,j,")][0]
        row = next(k for k, ln in enumerate(lines)
                   if ln.startswith("10,20,D,"))
        f = lines[row].split(",")
        f[6] = "0.612"  # T
        lines[row] = ",".join(f)
        open(edited, "w").write("\n".join(lines))
        vals = [10, 20, 3]
        for x in f[3:6]:
            k = round(Fr(x) * COORD_SCALE) & 0xFFFFFFFF
            vals += [k >> 16, k & 0xFFFF]
        vals += [round(Fr(x) * 10000) for x in f[6:9]]
        check(hdr >= 0 and ok(c.write_registers(40, vals, unit=1)),
              "PLC upload of (10, 20, D)")
        g2 = c.read_holding_registers(7, 2, unit=1)
        check(ok(g2) and regs_u32(g2.registers, 0) == gen + 1,
              "generation bumped by the update")
        for u16, w16 in [(1587, 3175), (1600, 3000), (5000, 5000)]:
            before[(u16, w16)] = compare_plc(c, edited, u16, w16,
                                             "after upload")
        c.close()

        # kill -9: the WAL brings back every acknowledged change
        d.stop(signal.SIGKILL)
        check(d.start(port), "it2nd restarts after kill -9")
        c = ModbusTcpClient("127.0.0.1", port=port)
        c.connect()
        st = c.read_holding_registers(0, 32, unit=1)
        check(ok(st) and st.registers[1] == 2 and
              regs_u32(st.registers, 7) == gen + 1 and st.registers[28] == 1,
              "after kill -9: solved, same generation, kind bspline")
        for key in [(0, 0), (3000, 7000), (1587, 3175)]:
            fr, _ = plc_eval(c, *key)
            check(fr is not None and fr == before[key],
                  f"after kill -9: results at {key} unchanged")
        c.close()
        # a clean stop writes a snapshot (version 4: memberships uploaded
        # over Modbus are stored as 'it2n' reads them, in Q30, which Q24
        # cannot hold; the results after the restart below are compared
        # bit for bit)
        d.stop(signal.SIGTERM)
        with open(os.path.join(state, "snapshot"), "rb") as fh:
            head = fh.read(12)
        check(head[:8] == b"IT2NSNP\0" and
              struct.unpack("<I", head[8:12])[0] == 4,
              f"snapshot version 4: {head!r}")
        check(d.start(port), "it2nd restarts from the snapshot")
        c = ModbusTcpClient("127.0.0.1", port=port)
        c.connect()
        for key in [(10000, 10000), (1587, 3175)]:
            fr, _ = plc_eval(c, *key)
            check(fr is not None and fr == before[key],
                  f"after restart: results at {key} unchanged")

        # reload (SIGHUP) turning the paper model on unit 2 into a B-spline
        # one, written in the file: replaced, preloaded again, and its
        # results are the B-spline interpolant of the paper data
        with open(conf, "a") as f:
            f.write("kind = bspline\n")
        d.p.send_signal(signal.SIGHUP)
        kind = None
        for _ in range(100):
            time.sleep(0.05)
            k = c.read_holding_registers(28, 3, unit=2)
            if ok(k) and k.registers[0] == 1:
                kind = k.registers
                break
        check(kind == [1, 6, 6], f"reload: unit 2 is a B-spline model now: {kind}")
        compare_plc_unit2 = c.readwrite_registers(read_address=128,
                                                  read_count=108,
                                                  write_address=64,
                                                  write_registers=[2500, 6000],
                                                  unit=2)
        rc, out, err = run(IT2N, "eval", "--kind", "bspline", paper,
                           "--decimals", "9", "--at", "0.25,0.6")
        want = {ln.split(",")[2]: [q24(x) for x in ln.split(",")[3:8]]
                for ln in out.strip().split("\n")[1:]}
        got = compare_plc_unit2.registers if ok(compare_plc_unit2) else []
        bad = [(fp, ci) for fi, fp in enumerate(FPS) for ci in (0, 1, 3, 4, 5)
               if len(got) < 108 or regs_u32(got, (fi * 6 + ci) * 2) !=
               f32_bits(want[fp][ci if ci < 2 else ci - 1])]
        check(rc == 0 and not bad,
              f"reload: unit 2 answers as it2n eval --kind bspline of the "
              f"paper data: {bad[:4]} {err}")
        fr, _ = plc_eval(c, 1587, 3175)
        check(fr == before[(1587, 3175)], "reload: unit 1 untouched")
        c.close()
    finally:
        d.stop(signal.SIGTERM)
        R.tidy(tmp, os.path.join(tmp, "it2nd.log"))
    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
