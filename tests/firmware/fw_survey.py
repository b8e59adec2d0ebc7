#!/usr/bin/python3
"""fw-survey (issue 21, Done when): a 64x64 uncertain survey
(examples/survey_64x64.csv, type-2 with z) goes from CSV through
'it2nctl push --kind bspline --link' (protocol v1.3: the 5-byte CONFIGURE)
into a real it2nd, is read back by a PLC over Modbus TCP and by the core on
emulated Cortex-M3 (qemu mps2-an385, examples/firmware/survey.c: the same
CSV compiled into flash, parsed and solved on the device), bit for bit at
320 query points (a 16 x 16 grid with corners and edges, 64 random), and
plotted. Also: a v1.2 peer's 4-byte CONFIGURE never turns the B-spline
model into a Bezier one, a B-spline push to a Bezier model and one beyond
the model's storage are refused; none changes anything. And the memory
table of docs/firmware.md is recomputed and checked against the image.

usage: fw_survey.py   (env: IT2ND, CTL, PTY, FW_ELF, SURVEY, FW_OUT)"""

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

from pymodbus.client import ModbusTcpClient

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

IT2ND, CTL, PTY, FW_ELF = (os.path.abspath(os.environ[k]) for k in ("IT2ND", "CTL", "PTY", "FW_ELF"))
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SURVEY = os.path.abspath(os.environ.get("SURVEY", os.path.join(ROOT, "examples", "survey_64x64.csv")))
OUT = os.environ.get("FW_OUT", os.path.join(ROOT, "build", "fw-survey"))
R = report.Report("fw-survey", quiet_ok=False)
check = R.check


def run(*args, timeout=120):
    p = subprocess.run([CTL, *args], capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def ok(r):
    return r is not None and not r.isError()


def status_regs(port, unit):
    c = ModbusTcpClient("127.0.0.1", port=port)
    if not c.connect():
        return None
    r = c.read_holding_registers(0, 32, unit=unit)
    c.close()
    return r.registers if ok(r) else None


def mcu_table():
    """docs/firmware.md "B-spline grids on an MCU": every row recomputed from
    the core's macros (IT2N_BSPLINE_DATA_RECS x 32 B + IT2N_BSPLINE_MODEL_WORDS
    x 4 B). Returns the documented 64 x 64 type-2 x, y, z storage."""
    text = open(os.path.join(ROOT, "docs", "firmware.md")).read()
    body = text.split("<!-- bspline-mcu: tests/firmware/fw_survey.py -->", 1)[1].strip().split("\n")
    rows = []
    for ln in body[2:]:
        if not ln.startswith("|"):
            break  # the table ends
        rows.append([c.strip() for c in ln.strip("|").split("|")])
    kinds = {"type-1 x, y": (1, 5), "type-1 x, y, z": (1, 6), "type-2 x, y": (7, 5), "type-2 x, y, z": (7, 6)}

    def size(n, nfp, nch):
        return (n + 1) ** 2 * nfp * 32 + (n + 3) ** 2 * nfp * nch * 4

    def largest(budget, nfp, nch):
        n = 1
        while size(n + 1, nfp, nch) <= budget:
            n += 1
        return f"{n + 1} × {n + 1} ({size(n, nfp, nch)} B)"

    bad = []
    for r in rows:
        if r[0] not in kinds:
            bad.append(f"unknown row {r[0]!r}")
            continue
        nfp, nch = kinds[r[0]]
        want = [r[0], str(nfp * 32 + nfp * nch * 4), str(size(63, nfp, nch)),
                largest(24 * 1024, nfp, nch), largest(112 * 1024, nfp, nch)]
        if r != want:
            bad.append(f"{r} != {want}")
    check(len(rows) == 4 and not bad, "docs/firmware.md B-spline memory table: " + ("; ".join(bad) or "4 rows current"))
    return size(63, 7, 6)


def main():
    tmp = tempfile.mkdtemp(prefix="fw-survey-")
    os.makedirs(OUT, exist_ok=True)
    procs = []
    daemon = qemu = None
    try:
        # the firmware runs on its own (no UART): start it first
        qlog = os.path.join(tmp, "qemu.log")
        qemu = subprocess.Popen(["qemu-system-arm", "-M", "mps2-an385", "-display", "none",
                                 "-serial", "null", "-semihosting-config", "enable=on,target=native",
                                 "-kernel", FW_ELF], stdin=subprocess.DEVNULL,
                                stdout=open(qlog, "w"), stderr=subprocess.STDOUT)
        p = subprocess.Popen([PTY], stdout=subprocess.PIPE, text=True)
        procs.append(p)
        link_a, link_b = p.stdout.readline().split()
        port = free_port()
        conf = os.path.join(tmp, "it2nd.conf")
        with open(conf, "w") as f:
            f.write(f"[daemon]\nstate_dir = {tmp}/state\n"
                    # nothing here tests durability (daemon-durability does):
                    # fdatasync would only slow the 1 510 PUTs
                    "fsync = no\nlink_backoff_max = 1\n"
                    f"[modbus]\ntcp_listen = 127.0.0.1:{port}\n"
                    "[model:1]\nkind = bspline\nn = 63\nm = 63\nz = yes\n"
                    "[model:2]\nunit_id = 2\npreload = paper\n"
                    f"[link:ctl]\ntype = serial\ndevice = {link_a}\n")
        dlog = os.path.join(tmp, "it2nd.log")
        daemon = subprocess.Popen([IT2ND, "-c", conf, "-f", "-v"], stdout=open(dlog, "w"),
                                  stderr=subprocess.STDOUT)
        for _ in range(200):
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.05)
        check(daemon.poll() is None, "it2nd starts with a B-spline model and a serial [link:]")
        link = ["--link", link_b, "--timeout", "20000"]

        # CSV -> it2nctl push --kind bspline over the link (v1.3 CONFIGURE)
        t0 = time.monotonic()
        rc, out, err = run("push", "--kind", "bspline", SURVEY, *link, "--model", "1", timeout=240)
        dt = time.monotonic() - t0
        check(rc == 0 and "pushed 28672 points" in out and "solved" in out,
              f"it2nctl push --kind bspline --link: 28672 points in {dt:.1f} s ({rc} {out.strip()} {err.strip()})")
        r = status_regs(port, 1)
        check(r is not None and r[1] == 2 and r[2] == 63 and r[3] == 63 and r[4] == 1 and r[28] == 1,
              f"PLC status: solved, 63 x 63 intervals, z, kind bspline ({r[:5] if r else r}, kind {r[28] if r else r})")
        gen = (r[7] << 16 | r[8]) if r else None
        dl = open(dlog).read()
        check("CONFIGURE model 1: bspline 63x63" in dl, "the daemon got the B-spline CONFIGURE (log)")

        # a v1.2 peer's 4-byte CONFIGURE (Bezier data) to the B-spline model:
        # refused with INVAL naming the kinds, nothing changed
        paper = os.path.join(ROOT, "examples", "paper_4x4.csv")
        rc, out, err = run("push", paper, *link, "--model", "1")
        r2 = status_regs(port, 1)
        check(rc == 2 and "holds a bspline model" in err and r2 is not None and r2[1] == 2 and
              r2[2] == 63 and (r2[7] << 16 | r2[8]) == gen,
              f"a Bezier (4-byte) CONFIGURE to the B-spline model: refused, model unchanged ({rc} {err.strip()})")
        # and the 5-byte one to a Bezier model
        r2 = status_regs(port, 2)
        rc, out, err = run("push", "--kind", "bspline", SURVEY, *link, "--model", "2")
        r3 = status_regs(port, 2)
        # (state, n, m, flags, generation: the request counters move)
        check(rc == 2 and "holds a bezier model" in err and r2 is not None and r3 is not None and
              r3[1:5] + r3[7:9] == r2[1:5] + r2[7:9] and r2[1] == 2,
              f"a B-spline CONFIGURE to a Bezier model: refused, model unchanged ({rc} {err.strip()})")

        # a grid beyond the model's storage (n = 69 > 63): RANGE with the
        # largest size, nothing changed
        big = os.path.join(tmp, "big.csv")
        with open(big, "w") as f:
            f.write("i,j,footprint,x,y,z,T,I,F\n")
            for i in range(70):
                for j in range(2):
                    f.write(f"{i},{j},D,{i},{j},0,0.5,0.25,0.125\n")
        rc, out, err = run("push", "--kind", "bspline", big, *link, "--model", "1")
        r2 = status_regs(port, 1)
        check(rc == 2 and "69 intervals, its model holds at most 63" in err and r2 is not None and
              r2[1] == 2 and r2[2] == 63 and (r2[7] << 16 | r2[8]) == gen,
              f"a CONFIGURE beyond the model's storage: RANGE, model unchanged ({rc} {err.strip()})")

        # the firmware's own solve of the same file on the emulated Cortex-M3
        try:
            qrc = qemu.wait(timeout=120)
        except subprocess.TimeoutExpired:
            qrc = None
        log = open(qlog, errors="replace").read()
        m = re.search(r"^SURVEY n (\d+) m (\d+) flags (\d+) entries (\d+) solve ms (\d+) storage bytes (\d+)",
                      log, re.M)
        check(qrc == 0 and "PASS survey firmware" in log and m is not None and
              m.group(1, 2, 3, 4) == ("63", "63", "1", "28672"),
              f"firmware: the compiled-in survey parsed and solved on the core (n = m = 63, z, 28672 entries) "
              f"(SysTick {m.group(5) if m else '?'} ms under qemu, not cycle-accurate), storage {m.group(6) if m else '?'} bytes")
        # the table's formula is the core's: the image's sizeof rec + coef
        check(m is not None and int(m.group(6)) == mcu_table(),
              f"firmware storage {m.group(6) if m else '?'} bytes = the documented 64 x 64 type-2 x, y, z figure")
        evals = len(re.findall(r"^EVAL ", log, re.M))
        check(evals == 320, f"firmware: {evals} evaluations (16 x 16 grid + 64 random)")
        shutil.copy(qlog, os.path.join(OUT, "qemu.log"))

        # the PLC's answers against the firmware's, bit for bit (every
        # float32 result and summary register, out_of_range)
        p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "tests", "firmware", "fw_check.py"),
                            str(port), qlog, "1"], capture_output=True, text=True, timeout=120)
        check(p.returncode == 0 and " 320 points, 17280 float32 values compared, each bit-identical" in p.stdout,
              f"PLC (Modbus TCP) reads bit for bit the firmware's evaluations: {p.stdout.strip()} {p.stderr[-500:]}")

        # plotted from the daemon (its coefficients over Modbus)
        png = os.path.join(OUT, "survey.png")
        rc, out, err = run("plot", "-o", png, "--tcp", f"127.0.0.1:{port}")
        check(rc == 0 and os.path.getsize(png) > 10000, f"it2nctl plot of the pushed survey: {png} ({rc} {err.strip()})")
    finally:
        for pr in [qemu, daemon] + procs:
            if pr is not None and pr.poll() is None:
                pr.send_signal(signal.SIGTERM)
                try:
                    pr.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    pr.kill()
        R.tidy(tmp, os.path.join(tmp, "it2nd.log"))
    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
