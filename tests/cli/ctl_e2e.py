#!/usr/bin/env python3
"""End-to-end test of it2nctl against a real it2nd.

Usage: ctl_e2e.py IT2NCTL IT2N IT2ND PTYBRIDGE

Starts it2nd in a temporary state directory with a Modbus TCP listener on a
free port in 23000..23999, a [link:] on one side of a pty pair (it2nctl
--link on the other side) and a Modbus RTU port on a second pty pair. Then,
as a user would:

* pushes data sets the daemon has never seen (generated with a fresh seed)
  through it2nctl over TCP, over the link (also through a relay dropping
  0.06 % of the bytes each way) and over RTU, and compares every
  answer (status, eval at several points with and without --summary,
  locate, net, sample with --summary/--footprint) with `it2n` run on the
  same file: over the link the text must be identical (memberships travel
  in Q30, PUT FINE, results exact Q24 on the wire; parameters Q2.30, so locate's u, w may differ by 1e-6);
  over Modbus memberships in [-1, 1] must be identical (float32 carries
  them exactly) and coordinates and memberships beyond 1 equal to float32
  precision, locate has no u, w and reports outside|noconv;
* watch prints a row per new generation (TCP polling and link EVENTs);
* plot draws the live model (PNG and SVG checked as images; the SVG path
  data equal to `it2n plot` on the pushed file, over TCP and the link);
* errors: bad CSV (the same FILE:LINE message as `it2n check`, exit 2,
  nothing sent), a value Modbus cannot carry (FILE:LINE, exit 2, nothing
  sent), unreachable daemon and silent link (exit 3), unsolved model and
  unknown unit/model (exit 2), usage errors (exit 1);
* the `<!-- run: it2nctl -->` blocks of docs/it2nctl.md and the EXAMPLES of
  it2nctl(1) run as written against the daemon ($IT2NCTL_TCP).
"""
import math
import os
import random
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
CTL, IT2N, IT2ND, PTY = (os.path.abspath(a) for a in sys.argv[1:5])
sys.argv[1:] = [IT2N]  # plot_export reads its binary from argv
from plot_export import png_info  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GEN = os.path.join(ROOT, "tests", "daemon", "gen_dataset.py")
R = report.Report("ctl-e2e", quiet_ok=True)  # ~200 checks: failures only
check = R.check


def run(*args, env=None, binary=None, timeout=60):
    p = subprocess.run([binary or CTL, *args], capture_output=True,
                       text=True, timeout=timeout, env=env)
    return p.returncode, p.stdout, p.stderr


def pty_pair(procs):
    p = subprocess.Popen([PTY], stdout=subprocess.PIPE, text=True)
    procs.append(p)
    a, b = p.stdout.readline().split()
    return a, b


# ---- comparison -------------------------------------------------------------

COORD = {"x", "y", "z"}
MEMB = {"T", "I", "F"}
F32 = 2.0 ** -23


def compare(what, got, want, mode, uw_tol=0.0):
    """got (it2nctl) against want (it2n), CSV text, as described above."""
    g, w = got.strip().split("\n"), want.strip().split("\n")
    if g[0] != w[0] or len(g) != len(w):
        check(False, f"{what}: header/rows differ:\n{g[:3]}\n{w[:3]} "
              f"({len(g)} vs {len(w)} lines)")
        return
    head = w[0].split(",")
    bad = []
    for k, (gl, wl) in enumerate(zip(g[1:], w[1:]), 2):
        gf, wf = gl.split(","), wl.split(",")
        # every row under its header (a --summary row with z had 11 fields
        # under 10 columns, in it2nctl and it2n alike)
        if len(gf) != len(head) or len(wf) != len(head):
            bad.append(f"line {k}: {len(gf)} / {len(wf)} fields under "
                       f"{len(head)} columns: {gl!r} vs {wl!r}")
            continue
        if len(gf) != len(wf):
            bad.append(f"line {k}: {gl!r} vs {wl!r}")
            continue
        for col, a, b in zip(head, gf, wf):
            if a == b:
                continue
            ok = False
            if col in ("u", "w") and head[2] == "footprint" and \
                    head[0] == "x" and mode == "modbus":
                ok = a == ""                 # locate: not in the map
            elif col == "status" and mode == "modbus":
                ok = a == "outside|noconv" and b in ("outside", "noconv")
            elif col in ("u", "w") and uw_tol:
                ok = abs(float(a) - float(b)) <= uw_tol
            elif mode == "modbus" and (col in COORD or col in MEMB):
                fb = float(b)
                exact = col in MEMB and abs(fb) <= 1.0
                ok = not exact and \
                    abs(float(a) - fb) <= abs(fb) * F32 + 1.5e-6
            if not ok:
                bad.append(f"line {k} {col}: {a} vs {b}")
    check(not bad, f"{what}: " + "; ".join(bad[:5]))


def status_of(conn):
    rc, out, err = run("status", *conn)
    check(rc == 0, f"status {conn}: rc {rc} {err}")
    lines = out.strip().split("\n")
    return dict(zip(lines[0].split(","), lines[1].split(",")))


def check_status(conn, csv, extra=()):
    """status against `it2n check` on the same file."""
    st = status_of(conn)
    rc, out, _ = run("check", csv, *extra, binary=IT2N)
    m = re.search(r"(\d+)x(\d+) grid \(n=(\d+), m=(\d+)\), (type-\d)[^,]*, "
                  r"coordinates ([xyz,]+), (\S+) parameters", out)
    check(m is not None, f"it2n check output: {out}")
    if m is None:
        return st
    n, mm = int(m.group(3)), int(m.group(4))
    fps = 1 if m.group(5) == "type-1" else 7
    want = {"state": "solved", "n": str(n), "m": str(mm),
            "type": m.group(5), "parameters": m.group(7),
            "points_present": str((n + 1) * (mm + 1) * fps),
            "points_required": str((n + 1) * (mm + 1) * fps)}
    got = {k: st.get(k) for k in want}
    check(got == want, f"status {conn}: {got} != {want}")
    want_xyz = "xyz" if m.group(6) == "x,y,z" else "xy"
    check(st.get("coordinates") == want_xyz and len(st) == 12 and
          st.get("kind") == "bezier",
          f"status coordinates: {st}")
    return st


def compare_all(label, conn, csv, mode, extra=(), grids=("5x5", "3x9")):
    # the last two are not in steps of 0.0001: Modbus sends them as float32
    ats = ["0,0", "1,1", "0.5,0.5", "0.25,0.75", "0.125,0.875", "1,0",
           "0.3,0.7", "0.0009765625,0.5", "0.6669921875,0.25"]
    args = [x for a in ats for x in ("--at", a)]
    uw = 1.5e-6 if mode == "link" else 0.0
    for summ in ((), ("--summary",)):
        rc, got, err = run("eval", *args, *summ, *conn)
        check(rc == 0, f"{label} eval: rc {rc} {err}")
        want = run("eval", csv, *args, *summ, *extra, binary=IT2N)[1]
        # u = 0.3 over a link is Q2.30 (the answer names what was used)
        compare(f"{label} eval{summ}", got, want, mode, uw_tol=uw)
    # locate where the surfaces are: every D data point's (x, y) from net
    rc, out, _ = run("sample", csv, "--grid", "3x3", "--footprint", "D",
                     *extra, binary=IT2N)
    xy = [ln.split(",")[3:5] for ln in out.strip().split("\n")[1:]]
    pts = [f"{float(x):.2f},{float(y):.2f}" for x, y in xy[::2]]
    pts.append("-1000,1000")  # outside every surface
    # dyadic, not in steps of 1/100: float32 over Modbus
    pts.append(f"{round(float(xy[4][0]) * 128) / 128:.7f},"
               f"{round(float(xy[4][1]) * 128) / 128:.7f}")
    args = [x for a in pts for x in ("--at", a)]
    rc, got, err = run("locate", *args, *conn)
    check(rc == 0, f"{label} locate: rc {rc} {err}")
    want = run("locate", csv, *args, *extra, binary=IT2N)[1]
    compare(f"{label} locate", got, want, mode, uw_tol=uw)
    rc, got, err = run("net", *conn)
    check(rc == 0, f"{label} net: rc {rc} {err}")
    compare(f"{label} net", got, run("solve", csv, *extra,
                                     binary=IT2N)[1], mode)
    for grid in grids:
        for opt in ((), ("--summary",), ("--footprint", "D")):
            if opt and opt[0] == "--footprint" and "type1" not in csv and \
                    mode != "modbus":
                opt = ("--footprint", "LL,D,RR", "--summary")
            rc, got, err = run("sample", "--grid", grid, *opt, *conn)
            check(rc == 0, f"{label} sample {grid} {opt}: rc {rc} {err}")
            want = run("sample", csv, "--grid", grid, *opt, *extra,
                       binary=IT2N)[1]
            compare(f"{label} sample {grid} {opt}", got, want, mode)
    rc, got, _ = run("eval", "--at", "0.5,0.5", "--decimals", "9", *conn)
    want = run("eval", csv, "--at", "0.5,0.5", "--decimals", "9", *extra,
               binary=IT2N)[1]
    if mode == "link":
        compare(f"{label} eval --decimals 9", got, want, mode)
        # it2nctl takes it2n's 0..9 decimals (it once took 6..9 only)
        rc, got2, err = run("eval", "--at", "0.5,0.5", "--decimals", "2", *conn)
        want2 = run("eval", csv, "--at", "0.5,0.5", "--decimals", "2", *extra, binary=IT2N)[1]
        check(rc == 0 and got2 == want2, f"{label} eval --decimals 2: {rc} {err} {got2!r} vs {want2!r}")
        for grid in grids:  # the daemon's SAMPLE nodes are it2n's
            got = run("sample", "--grid", grid, "--decimals", "9", *conn)[1]
            want = run("sample", csv, "--grid", grid, "--decimals", "9",
                       *extra, binary=IT2N)[1]
            compare(f"{label} sample {grid} --decimals 9", got, want, mode)


def push(label, conn, csv, extra=()):
    rc, out, err = run("push", csv, *extra, *conn)
    check(rc == 0 and ": pushed " in out and "solved" in out,
          f"{label} push: rc {rc} {out} {err}")


# ---- the test -----------------------------------------------------------------

def main():
    same_path_selftest()
    tmp = tempfile.mkdtemp(prefix="it2nctl-e2e.")
    procs = []
    daemon = None
    try:
        link_a, link_b = pty_pair(procs)
        rtu_a, rtu_b = pty_pair(procs)
        dead_a, dead_b = pty_pair(procs)  # nobody on the other side
        port = free_port()
        conf = os.path.join(tmp, "it2nd.conf")
        with open(conf, "w") as f:
            f.write(f"[daemon]\nstate_dir = {tmp}/state\n"
                    "snapshot_interval = 3600\nlink_backoff_max = 1\n"
                    f"[modbus]\ntcp_listen = 127.0.0.1:{port}\n"
                    f"[rtu:bus]\ndevice = {rtu_a}\nbaud = 115200\n"
                    "[model:1]\nunit_id = 1\npreload = paper\n"
                    "[model:2]\nunit_id = 2\nn = 3\nm = 3\n"
                    "[model:3]\nunit_id = 3\nn = 3\nm = 3\n"
                    "[model:4]\nunit_id = 4\npreload = paper\n"
                    "write_protect = yes\n"
                    f"[link:ctl]\ntype = serial\ndevice = {link_a}\n"
                    "baud = 115200\n")
        log = open(os.path.join(tmp, "daemon.log"), "w")
        daemon = subprocess.Popen([IT2ND, "-c", conf, "-f", "-v"],
                                  stdout=log, stderr=subprocess.STDOUT)
        tcp = ["--tcp", f"127.0.0.1:{port}"]
        for _ in range(200):
            if run("status", *tcp)[0] == 0:
                break
            time.sleep(0.05)
        link = ["--link", link_b]
        rtu = ["--rtu", rtu_b, "--unit", "3", "--baud", "115200"]
        seed = int(os.environ.get("CTL_SEED", "0")) or random.randint(1, 10 ** 6)  # CTL_SEED=N replays a run
        print(f"ctl e2e: port {port}, data seed {seed}")

        def gen(n, m, s, dec):
            path = os.path.join(tmp, f"gen_{n}x{m}_{s}_{dec}.csv")
            with open(path, "w") as f:
                subprocess.run([sys.executable, GEN, str(n), str(m), str(s),
                                str(dec)], stdout=f, check=True)
            return path

        # -- Modbus TCP: a 5x4 grid with coordinates in 1/100 -------------
        g_tcp = gen(4, 3, seed, 2)
        push("tcp", tcp, g_tcp)
        st = check_status(tcp, g_tcp)
        compare_all("tcp", tcp, g_tcp, "modbus")
        # z coordinates
        push("tcp z", tcp, os.path.join(ROOT, "examples/z_3x3.csv"))
        check_status(tcp, os.path.join(ROOT, "examples/z_3x3.csv"))
        compare_all("tcp z", tcp, os.path.join(ROOT, "examples/z_3x3.csv"),
                    "modbus", grids=("3x3",))

        # -- link: a 4x6 grid with 4-decimal coordinates ------------------
        g_link = gen(3, 5, seed + 1, 4)
        push("link", link, g_link)
        check_status(link, g_link)
        # memberships travel in Q30 (PUT FINE, protocol v1.3): the
        # reference is 'it2n' on the very CSV
        compare_all("link", link, g_link, "link", grids=("5x5", "4x4", "7x3"))
        t1 = os.path.join(ROOT, "examples/type1_4x3.csv")
        push("link type-1", link, t1)
        check_status(link, t1)
        compare_all("link type-1", link, t1, "link", grids=("5x5",))

        # -- the link again through a relay dropping bytes both ways -----
        t_lossy = time.time()
        relay_out = os.path.join(tmp, "lossy_pty")
        relay = subprocess.Popen(
            [sys.executable, os.path.join(ROOT, "tests/firmware/lossy_relay.py"),
             link_b, relay_out, "600", str(seed)],
            stdout=open(os.path.join(tmp, "relay.log"), "w"))
        procs.append(relay)
        for _ in range(500):
            if os.path.exists(relay_out):
                break
            time.sleep(0.02)
        lossy = ["--link", open(relay_out).read().strip(), "--timeout", "30000"]
        g_lossy = gen(2, 3, seed + 3, 6)
        push("lossy link", lossy, g_lossy)
        check_status(lossy, g_lossy)
        for cmd, ref in ((["net"], ["solve"]),
                         (["sample", "--grid", "5x5", "--summary"],
                          ["sample", "--grid", "5x5", "--summary"])):
            rc, got, err = run(*cmd, *lossy)
            check(rc == 0, f"lossy {cmd}: rc {rc} {err}")
            compare(f"lossy link {cmd}", got,
                    run(ref[0], g_lossy, *ref[1:], binary=IT2N)[1], "link")
        relay.terminate()
        relay.wait()
        procs.remove(relay)
        last = open(os.path.join(tmp, "relay.log")).read().strip()
        last = last.split("\n")[-1] if last else ""
        drops = [int(d) for d in re.findall(r"dropped (\d+)", last)]
        check(len(drops) == 2 and sum(drops) > 0,
              f"the relay dropped nothing: {last!r}")
        print(f"ctl e2e: lossy link ({time.time() - t_lossy:.1f} s): {last}")

        # -- the other float32 word orders: DCBA from here on (SIGHUP) ----
        with open(conf) as f:
            text = f.read()
        with open(conf, "w") as f:
            f.write(text.replace("[modbus]\n",
                                 "[modbus]\nfloat_word_order = DCBA\n"))
        daemon.send_signal(signal.SIGHUP)
        for _ in range(100):
            if read_reg(port, 21) == 3:
                break
            time.sleep(0.05)
        check(read_reg(port, 21) == 3, "word order DCBA not reloaded")

        # -- RTU: chord-length parameters on unit 3 -----------------------
        ch = os.path.join(ROOT, "examples/chord_5x4.csv")
        push("rtu", rtu, ch, extra=("--chord",))
        check_status(rtu, ch, extra=("--chord",))
        compare_all("rtu", rtu, ch, "modbus", extra=("--chord",),
                    grids=("5x5",))

        # -- progress bar on a terminal only -----------------------------
        rc, out, err = run("push", g_tcp, *tcp)
        check(rc == 0 and err == "", f"push to a pipe printed {err!r}")
        mfd, sfd = os.openpty()
        p = subprocess.Popen([CTL, "push", g_tcp, *tcp],
                             stdout=subprocess.PIPE, stderr=sfd)
        os.close(sfd)
        tty = b""
        while True:
            try:
                chunk = os.read(mfd, 4096)
            except OSError:
                break
            if not chunk:
                break
            tty += chunk
        p.wait()
        os.close(mfd)
        bars = re.findall(rb"\rpush \[([#.]{40})\] (\d+)/140 points", tty)
        check(p.returncode == 0 and len(bars) == 140 and
              bars[-1] == (b"#" * 40, b"140") and bars[0][1] == b"1",
              f"progress bar on a tty: {tty[:120]!r}... {len(bars)} updates")

        # -- the link data set cannot go over Modbus: FILE:LINE, nothing sent
        before = status_of(tcp)["generation"]
        rc, out, err = run("push", g_link, *tcp)
        m = re.match(r"(.*):(\d+): (\w)=(\S+) is not a multiple of 1/100", err)
        check(rc == 2 and m is not None and m.group(1) == g_link,
              f"unrepresentable push: rc {rc} {err!r}")
        if m:
            line = open(g_link).read().split("\n")[int(m.group(2)) - 1]
            check(m.group(4).rstrip("0") in line, f"line {line} vs {err}")
        check(status_of(tcp)["generation"] == before,
              "a refused push changed the model")

        # -- bad CSV: it2n's message, exit 2, daemon untouched ------------
        bad = os.path.join(tmp, "bad.csv")
        with open(g_tcp) as f:
            rows = f.read().split("\n")
        rows[5] = rows[5].rsplit(",", 3)[0] + ",1.2,0.5,0.5"
        with open(bad, "w") as f:
            f.write("\n".join(rows))
        rc, _, err = run("push", bad, *tcp)
        rc2, _, err2 = run("check", bad, binary=IT2N)
        check(rc == 2 and err == err2 and err.startswith(bad + ":6: T=1.2"),
              f"bad CSV: rc {rc} {err!r} vs it2n {err2!r}")
        check(status_of(tcp)["generation"] == before, "bad CSV changed it")
        rc, _, err = run("push", os.path.join(tmp, "missing.csv"), *tcp)
        check(rc == 2 and "missing.csv: cannot open: No such file" in err,
              f"missing file: {rc} {err!r}")

        # -- connection errors: exit 3 with a clear message ---------------
        closed = free_port()
        rc, _, err = run("status", "--tcp", f"127.0.0.1:{closed}")
        doc_errs = [err.replace(f"127.0.0.1:{closed}", "127.0.0.1:1502")]
        check(rc == 3 and f"cannot connect to 127.0.0.1:{closed}" in err
              and "is it2nd running?" in err, f"unreachable: {rc} {err!r}")
        t0 = time.time()
        rc, _, err = run("status", "--link", dead_b, "--timeout", "300")
        doc_errs.append(err.replace(dead_b, "/dev/ttyUSB1")
                        .replace("300 ms", "3000 ms"))
        check(rc == 3 and "no answer from it2nd within 300 ms" in err and
              time.time() - t0 < 5, f"silent link: {rc} {err!r}")
        # a TCP peer that accepts and never answers
        mute = socket.socket()
        mute.bind(("127.0.0.1", free_port()))
        mute.listen(4)
        rc, _, err = run("status", "--tcp",
                         "127.0.0.1:%d" % mute.getsockname()[1],
                         "--timeout", "300")
        mute.close()
        check(rc == 3 and "read status: no answer (timeout)" in err,
              f"mute TCP peer: {rc} {err!r}")
        rc, _, err = run("status", "--link", os.path.join(tmp, "nodev"))
        check(rc == 3 and "cannot open" in err, f"no device: {rc} {err!r}")
        # -- errors that say what is wrong (issue 18 item 4) ---------------
        for bad, msg in (("127.0.0.1:notaport", "the port is not a number 1..65535"),
                         ("127.0.0.1:99999", "the port is not a number 1..65535"),
                         (":1502", "the host is empty"),
                         ("::1", "an IPv6 address needs brackets"),
                         ("[::1", "no closing ']'")):
            rc, _, err = run("status", "--tcp", bad)
            check(rc == 1 and msg in err and "is it2nd running" not in err,
                  f"--tcp {bad}: {rc} {err!r}")
        rc, _, err = run("status", "--tcp", "no-such-host.invalid:1502")
        # the resolver's words depend on the machine's DNS setup
        doc_errs.append(re.sub(r"(no-such-host\.invalid'): [^(]*\(", r"\1: Name or service not known (", err))
        check(rc == 3 and "cannot resolve host 'no-such-host.invalid'" in err
              and "is it2nd running" not in err, f"unresolvable host: {rc} {err!r}")
        rc, _, err = run("status", "--rtu", "/dev/ttyUSB7")
        doc_errs.append(err)
        check(rc == 3 and "cannot open serial device /dev/ttyUSB7" in err
              and "is it2nd running" not in err, f"missing RTU device: {rc} {err!r}")
        rc, _, err = run("status", "--rtu", "/dev/ttyUSB7", "--unit", "255")
        check(rc == 1 and "RTU unit ids are 0..247" in err, f"RTU unit 255: {rc} {err!r}")
        # options before the command
        rc0, out0, _ = run("status", *tcp)
        for args in ((*tcp, "status"), ("--unit", "1", *tcp, "status", "--timeout", "3000")):
            rc, out, err = run(*args)
            check(rc == rc0 == 0 and out == out0, f"it2nctl {' '.join(args)}: {rc} {out!r} {err!r}")
        # unit 255 (and 0) are asked of the daemon, not refused: this
        # configuration has no default model, so the daemon answers 0B
        for u in ("0", "255"):
            rc, _, err = run("status", *tcp, "--unit", u)
            check(rc == 2 and "exception 0B" in err, f"--unit {u}: {rc} {err!r}")
        # -- refusals: exit 2 ---------------------------------------------
        rc, _, err = run("eval", "--at", "0,0", *tcp, "--unit", "2")
        doc_errs.append(err)
        check(rc == 2 and "the model is not solved (state empty" in err,
              f"unsolved: {rc} {err!r}")
        rc, _, err = run("status", *tcp, "--unit", "9")
        doc_errs.append(err)
        check(rc == 2 and "exception 0B" in err, f"unit 9: {rc} {err!r}")
        rc, _, err = run("status", *link, "--model", "9")
        check(rc == 2 and "no such model" in err, f"model 9: {rc} {err!r}")
        # the errors of docs/it2nctl.md, produced here
        ddir = os.path.join(tmp, "derr")
        os.mkdir(ddir)
        paper = open(os.path.join(ROOT, "examples/paper_4x4.csv")).read()
        lines = paper.split("\n")
        lines[5] = lines[5].replace(",0.4,0.7,0.2", ",1.2,0.7,0.2")
        open(os.path.join(ddir, "data.csv"), "w").write("\n".join(lines))
        p = subprocess.run([CTL, "push", "data.csv", *tcp], cwd=ddir,
                           capture_output=True, text=True)
        doc_errs.append(p.stderr)
        lines = paper.split("\n")
        lines[2] = lines[2].replace("-21,", "-21.0625,")
        open(os.path.join(ddir, "data.csv"), "w").write("\n".join(lines))
        p = subprocess.run([CTL, "push", "data.csv", *tcp], cwd=ddir,
                           capture_output=True, text=True)
        check(p.returncode == 2, f"doc push x=-21.0625: {p.returncode}")
        doc_errs.append(p.stderr)
        doc = open(os.path.join(ROOT, "docs", "it2nctl.md")).read().split("\n")
        for e in doc_errs:
            e = e.strip().replace(f"127.0.0.1:{port}", "127.0.0.1:1502")
            check(e in doc, f"docs/it2nctl.md lacks the error {e!r}")
        before4 = status_of(tcp + ["--unit", "4"])
        rc, _, err = run("push", g_tcp, *tcp, "--unit", "4")
        after4 = status_of(tcp + ["--unit", "4"])
        check(rc == 2 and "configure: exception 02" in err and
              [after4[k] for k in ("state", "n", "generation")] ==
              [before4[k] for k in ("state", "n", "generation")],
              f"write-protected unit: {rc} {err!r}")
        # -- usage errors: exit 1 ------------------------------------------
        for args, msg in ((["eval"], "eval needs at least one --at"),
                          (["frob"], "unknown command 'frob'"),
                          (["sample"], "sample needs --grid RxC"),
                          (["push"], "missing DATA.csv"),
                          (["eval", "--at", "2,0"], "must lie in [0,1]"),
                          (["status", "--tcp", "a", "--link", "b"],
                           "give one of --tcp, --rtu and --link"),
                          (["plot", "-o", "x.gif"], "must end in .png")):
            rc, _, err = run(*args, *([] if "--tcp" in args else tcp))
            check(rc == 1 and msg in err and "Try 'it2nctl" in err,
                  f"usage {args}: {rc} {err!r}")

        # -- watch: one row per new generation ----------------------------
        watchers = [subprocess.Popen([CTL, "watch", "--count", "2", *c],
                                     stdout=subprocess.PIPE, text=True)
                    for c in (tcp, link)]
        # each has printed its header and first row before the change
        first = [wp.stdout.readline() + wp.stdout.readline()
                 for wp in watchers]
        g_w = gen(2, 2, seed + 2, 2)
        push("watch trigger", tcp, g_w)
        for c, wp, head in zip(("tcp", "link"), watchers, first):
            try:
                out = head + wp.communicate(timeout=10)[0]
            except subprocess.TimeoutExpired:
                wp.kill()
                out = head + wp.communicate()[0]
            rows = [dict(zip(out.split("\n")[0].split(","), ln.split(",")))
                    for ln in out.strip().split("\n")[1:]]
            gens = [int(r["generation"]) for r in rows]
            check(wp.returncode == 0 and len(gens) == 2 and gens[1] > gens[0]
                  and rows[1]["state"] == "solved",
                  f"watch {c}: rc {wp.returncode} {out!r} (the push's committed generation, "
                  "not a transient incomplete one)")

        # -- plot the live model ------------------------------------------
        png = os.path.join(tmp, "live.png")
        rc, _, err = run("plot", "-o", png, "--membership", "T", *tcp)
        check(rc == 0, f"plot png: {rc} {err}")
        try:
            w, h, colours, ink = png_info(png)
            check((w, h) == (900, 700) and colours >= 16 and ink >= 0.02,
                  f"plot png: {w}x{h}, {colours} colours, {ink:.1%} ink")
        except (OSError, ValueError) as e:
            check(False, f"plot png invalid: {e}")
        # the live model drawn as `it2n plot` draws the file: the same
        # surfaces and nets (SVG path data; only the title differs)
        for c, label in ((tcp, "tcp"), (link, "link")):
            push(f"plot {label}", c, g_tcp)
            mine, ref = (os.path.join(tmp, f"{label}_{k}.svg")
                         for k in ("ctl", "it2n"))
            rc, _, err = run("plot", "--membership", "T", "-o", mine, *c)
            run("plot", g_tcp, "--membership", "T", "-o", ref, binary=IT2N)
            pm, pr = visible(svg_paths(mine)), visible(svg_paths(ref))
            same = same_drawings(pm, pr)
            check(rc == 0 and len(pm) == len(pr) >= 50 and same == len(pr),
                  f"plot {label} vs it2n plot: rc {rc} {err} "
                  f"{same}/{len(pr)} paths equal ({len(pm)} drawn)")
        # plot --follow: redrawn on every new solved generation, the file
        # replaced whole; a push's transient generations are not drawn
        fsvg = os.path.join(tmp, "follow.svg")
        fp = subprocess.Popen([CTL, "plot", "--follow", "--count", "2", "--membership", "T",
                               "-o", fsvg, *tcp], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
        first = fp.stdout.readline()
        g_f = gen(3, 3, seed + 7, 2)
        push("plot --follow trigger", tcp, g_f)
        try:
            out, ferr = fp.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            fp.kill()
            out, ferr = fp.communicate()
        lines = (first + out).strip().split("\n")
        gens = [int(ln.split()[1].rstrip(":")) for ln in lines if ln.startswith("generation ")]
        st = status_of(tcp)
        ref = os.path.join(tmp, "follow_ref.svg")
        run("plot", g_f, "--membership", "T", "-o", ref, binary=IT2N)
        pm, pr = visible(svg_paths(fsvg)), visible(svg_paths(ref))
        same = same_drawings(pm, pr)
        # gens[1] may be the push's last upload (the model complete and
        # solved: a solved generation) or its commit, one later: which one
        # the follower wakes for depends on scheduling; the drawing must be
        # the pushed data's either way.
        check(fp.returncode == 0 and len(gens) == 2 and gens[0] < gens[1] <= int(st["generation"])
              and len(pm) == len(pr) >= 50 and same == len(pr)
              and not [n for n in os.listdir(tmp) if ".part" in n],
              f"plot --follow: rc {fp.returncode} {lines} {ferr!r}, status gen {st['generation']}, "
              f"{same}/{len(pr)} paths as it2n plot of the pushed file")
        push("plot", link, g_link)
        svg = os.path.join(tmp, "band.svg")
        rc, _, err = run("plot", "-o", svg, "--interval", "--size", "600x400",
                         *link)
        text = open(svg).read() if os.path.exists(svg) else ""
        check(rc == 0 and 'width="600"' in text and text.count("<path") >= 50,
              f"plot svg: {rc} {err} {len(text)} bytes")

        # -- the documented commands, as written --------------------------
        env = dict(os.environ, IT2NCTL_TCP=f"127.0.0.1:{port}",
                   PATH=os.path.dirname(CTL) + os.pathsep +
                   os.path.dirname(IT2N) + os.pathsep + os.environ["PATH"])
        blocks = doc_blocks(os.path.join(ROOT, "docs", "it2nctl.md"))
        blocks += doc_blocks(os.path.join(ROOT, "README.md"))
        blocks += man_examples(os.path.join(ROOT, "cli", "it2nctl", "it2nctl.1"))
        check(len(blocks) >= 2, "docs: no marked blocks")
        scratch = os.path.join(tmp, "docs")
        os.mkdir(scratch)
        shutil.copytree(os.path.join(ROOT, "examples"),
                        os.path.join(scratch, "examples"),
                        ignore=shutil.ignore_patterns("firmware", "instrument"))
        for where, text in blocks:
            p = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", text],
                               cwd=scratch, env=env, capture_output=True,
                               text=True, timeout=120)
            check(p.returncode == 0, f"{where}: exit {p.returncode}: "
                  f"{p.stderr.strip()[-400:]}")
    finally:
        if daemon is not None:
            daemon.terminate()
            try:
                daemon.wait(timeout=10)
            except subprocess.TimeoutExpired:
                daemon.kill()
        for p in procs:
            p.terminate()
            p.wait()
        R.tidy(tmp)
    return R.finish()


def read_reg(port, addr, unit=1):
    """One holding register over Modbus TCP (FC 03), or None."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            s.sendall(struct.pack(">HHHBBHH", 7, 0, 6, unit, 3, addr, 1))
            r = s.recv(64)
            return struct.unpack(">H", r[9:11])[0] if len(r) == 11 else None
    except OSError:
        return None


NUM = re.compile(r"-?\d+(?:\.\d+)?")


def same_path(a, b):
    """Equal SVG path data, coordinates within 0.05 px (the model over
    Modbus has float32 control points: a sample may move by 0.01 px). The
    first or last point of a path may also slide along its segment, by up
    to 0.5 px and within 0.05 px of its line: hidden-line removal ends a
    visible piece where it passes behind another surface, and where the two
    meet at a shallow angle that end moves along the piece by several times
    the samples' 0.01 px (CTL_SEED=638218: 0.06 px)."""
    if NUM.sub("#", a) != NUM.sub("#", b):
        return False
    (sa, da), (sb, db) = a.split("|", 1), b.split("|", 1)
    near = all(abs(float(x) - float(y)) <= 0.05 for x, y in zip(NUM.findall(sa), NUM.findall(sb)))
    va, vb = [float(x) for x in NUM.findall(da)], [float(x) for x in NUM.findall(db)]
    if not near or len(va) % 2 or len(va) < 4:
        return near and all(abs(x - y) <= 0.05 for x, y in zip(va, vb))
    pa, pb = list(zip(va[0::2], va[1::2])), list(zip(vb[0::2], vb[1::2]))
    last = len(pa) - 1
    for k, (p, q) in enumerate(zip(pa, pb)):
        if abs(p[0] - q[0]) <= 0.05 and abs(p[1] - q[1]) <= 0.05:
            continue
        if k not in (0, last):
            return False
        n = pb[1] if k == 0 else pb[last - 1]  # the end's neighbour: the segment's direction
        dx, dy, ex, ey = n[0] - q[0], n[1] - q[1], p[0] - q[0], p[1] - q[1]
        length = math.hypot(dx, dy)
        if length == 0 or abs(ex * dy - ey * dx) / length > 0.05 or math.hypot(ex, ey) > 0.5:
            return False
    return True


def visible(paths):
    """The paths at least 0.1 px long: where a hidden-line piece is only
    hundredths of a pixel long, the live model's float32 control points can
    hide it altogether (CTL_SEED=819349: a 0.036 px piece drawn from the
    file only)."""
    out = []
    for p in paths:
        v = [float(x) for x in NUM.findall(p.split("|", 1)[1])]
        pts = list(zip(v[0::2], v[1::2]))
        if len(v) % 2 or sum(math.dist(a, b) for a, b in zip(pts, pts[1:])) >= 0.1:
            out.append(p)
    return out


def same_path_selftest():
    """same_path against the pair that failed (CTL_SEED=638218) and what it
    must still refuse."""
    ref = "stroke='rgb( 0, 68, 27)'|M413.86,480.46 L409.05,481.81  "
    check(same_path("stroke='rgb( 0, 68, 27)'|M413.80,480.48 L409.05,481.81  ", ref),
          "same_path: a clipped end 0.06 px along its segment refused")
    check(not same_path("stroke='rgb( 0, 68, 27)'|M413.86,480.56 L409.05,481.81  ", ref),
          "same_path: an end 0.1 px across its segment accepted")
    check(not same_path("stroke='rgb( 0, 68, 27)'|M414.86,480.18 L409.05,481.81  ", ref),
          "same_path: an end 1 px along its segment accepted")
    check(not same_path("stroke='rgb( 0, 68, 27)'|M1,1 L409.11,481.79 L2,2",
                        "stroke='rgb( 0, 68, 27)'|M1,1 L409.05,481.81 L2,2"),
          "same_path: an inner point 0.06 px away accepted")
    check(not same_path("stroke='rgb( 0, 68, 28)'|M413.86,480.46 L409.05,481.81  ", ref),
          "same_path: another colour accepted")
    tiny = "stroke='rgb(116, 196, 118)' stroke-dasharray='3.0,4.8'|M534.42,307.37 L534.40,307.40  "
    short = "stroke='rgb(116, 196, 118)'|M534.42,307.37 L534.30,307.50 L534.20,307.50"
    check(visible([tiny, short, ref]) == [short, ref],
          "visible: a 0.036 px piece kept or a 0.28 px one dropped")


def svg_paths(path):
    """Every drawn path as 'style|data' (its attributes before d= and its
    data): what is drawn, how."""
    if not os.path.exists(path):
        return []
    return ["%s|%s" % (re.sub(r"\s+", " ", st).strip(), d) for st, d in
            re.findall(r"<path([^>]*?)\sd=[\"']([^\"']*)", open(path).read())]


def same_drawings(pm, pr):
    """How many paths of pr have a path in pm drawn alike (same_path), in
    any order: hidden-line removal emits the same segments in an order
    that tiny float32 differences of the live model can change."""
    pool = {}
    for a in pm:
        pool.setdefault(NUM.sub("#", a), []).append(a)
    same = 0
    for b in pr:
        cands = pool.get(NUM.sub("#", b), [])
        for k, a in enumerate(cands):
            if same_path(a, b):
                same += 1
                del cands[k]
                break
    return same


def doc_blocks(path):
    lines = open(path).read().split("\n")
    out = []
    for k, ln in enumerate(lines):
        if ln.strip() == "<!-- run: it2nctl -->":
            end = next(e for e in range(k + 2, len(lines))
                       if lines[e].strip() == "```")
            out.append((f"{path}:{k + 2}", "\n".join(lines[k + 2:end])))
    return out


def man_examples(path):
    lines = open(path).read().split("\n")
    start = lines.index(".SH EXAMPLES")
    nf = lines.index(".nf", start)
    fi = lines.index(".fi", nf)
    return [(f"{path}:{nf + 2}", "\n".join(ln.replace("\\-", "-")
                                            for ln in lines[nf + 1:fi]))]


if __name__ == "__main__":
    sys.exit(main())
