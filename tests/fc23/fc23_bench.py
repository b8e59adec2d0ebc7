#!/usr/bin/python3
"""FC 23 benchmark (issue 8 item 9): it2nd's full query against a bare
libmodbus server answering FC 23 of the same sizes, in one run.

For each connection count (1, 8, 32 by default) the same load generator
(fc23_load: N threads, one libmodbus TCP connection each, fixed duration,
every answer checked) runs against the bare server (fc23_bare) and against
it2nd (paper model on unit 1), alternately, round after round until the 95 %
confidence intervals of its ratios (throughput, server CPU per request, p99
latency) lie within +-5 % (at least --min-rounds, at most --rounds; at 1 connection
the throughput ratio's within +-0.5 %, at most --fine-rounds); the figure per
side is the geometric mean of its rounds, the ratio their quotient (the
geometric mean of the per-round ratios), with its interval in the row
(tests/bench/mcu/results.py ratio_interval). A target is met only when the
whole interval meets it.

--smoke: a couple of seconds, in make test: checks that every answer is
correct under concurrency (8 connections), never a time; writes under
build/ only.
"""
import argparse
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest.ports import free_port  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench", "mcu"))
from results import PRECISION, precise, ratio_interval, row  # noqa: E402

# Issue 22: it2nd answers as fast as the bare libmodbus server and spends
# no more server CPU per request (both ratios' whole intervals).
TARGET = 1.0
CPU_TARGET = 1.0
# ... and its p99 latency under 32 connections is no longer than the bare
# server's (each round's p99 over all connections, tests/fc23/fc23_load.c).
LAT_TARGET = 1.0
LAT_CONNS = 32
# At 1 connection both servers wait on the same client round trip (about
# 40 us, most of it the kernel's wake-ups on either side), so the
# throughput ratio lies within about 1 % of its target, while one round's
# ratio spreads by about 1.4 % (round_ratios): an interval of +-5 %, or the
# +-0.7 % of 15 rounds, cannot say on which side of the target it lies.
# There the rounds go on until the throughput ratio's interval is within
# +-FINE_PRECISION (about 30 rounds at that spread), at most --fine-rounds.
# The rule looks at the interval's width only, never at the target, so it
# does not favour either answer (issue 22).
FINE_CONNS = 1
FINE_PRECISION = 0.005


def thr_precision(n):
    """The width the throughput ratio's rounds aim at, n connections."""
    return FINE_PRECISION if n == FINE_CONNS else PRECISION

# Why a ratio can fall short (callgrind, per request at 8 connections,
# `make bench-fc23-callgrind`): it2nd runs about 3 100 user-space
# instructions per FC 23 request, the bare server about 1 200: the core's
# evaluation of the query is about 1 630 of them (35 of the 42 surfaces
# carry data; the bare server evaluates nothing), the float conversion of
# the 54 results about 230, framing, map and request handling the rest.
# What it2nd saves is in the kernel: with io = auto it waits, reads and
# replies through io_uring (daemon/loop.c), one io_uring_enter per wake-up
# (strace -c: 1.0 per request at 1 connection, fewer when several clients
# are served per wake-up), where the bare server makes a poll, a recv and a
# send per request. At 1 connection the client's round trip bounds both
# servers' throughput. The query points vary: each connection cycles
# through 256 (u, w) points over [0, 1]^2, consecutive requests differ, so
# every request is evaluated (fc23_load.c).
REASON = ("it2nd runs about 3 300 user-space instructions per request (make bench-fc23-callgrind, 8 "
          "connections) where the bare server runs about 1 200 (the core's evaluation of the query: about 1 900 "
          "of them); it2nd (io = %s) makes one io_uring_enter per wake-up, each connection's read armed once "
          "(multishot), where the bare server makes a poll, a recv and a send per request; "
          "at 1 connection the client's round trip bounds both servers' throughput; this run's user + kernel "
          "CPU per request (/proc clock ticks, coarse): %s; with the client on the same 2 cores, other jobs "
          "too (load_average), the per-round ratios spread (round_ratios in bench/fc23.json)")


def cpu_split_text(split):
    return "; ".join("%s connection(s): it2nd %.2f + %.2f us, bare %.2f + %.2f us"
                     % (n, v["it2nd"][0], v["it2nd"][1], v["bare"][0], v["bare"][1])
                     for n, v in sorted(split.items(), key=lambda kv: int(kv[0])))


def cpu_times(pid):
    """User and system CPU seconds of process pid (every thread)."""
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    tck = os.sysconf("SC_CLK_TCK")
    return int(fields[11]) / tck, int(fields[12]) / tck


class Bare:
    def __init__(self, exe, mode="framed"):
        self.p = subprocess.Popen([exe, "0", mode], stdout=subprocess.PIPE, text=True)
        line = self.p.stdout.readline().split()
        if len(line) != 2 or line[0] != "port":
            raise SystemExit("fc23: bare server did not start")
        self.port = int(line[1])

    def stop(self):
        self.p.send_signal(signal.SIGTERM)
        self.p.wait(10)


class It2nd:
    def __init__(self, exe, tmp, port, conns, io="auto", prefix=(), tag=None):
        tag = tag or io
        self.state = os.path.join(tmp, "state-" + tag)
        os.makedirs(self.state, exist_ok=True)
        self.conf = os.path.join(tmp, "it2nd-%s.conf" % tag)
        with open(self.conf, "w") as f:
            f.write("[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\nio = %s\n"
                    "[modbus]\ntcp_listen = 127.0.0.1:%d\nmax_clients = %d\n"
                    "[model:1]\nunit_id = 1\npreload = paper\n" % (self.state, io, port, max(conns, 32) + 8))
        self.log = open(os.path.join(tmp, "it2nd-%s.log" % tag), "w")
        self.p = subprocess.Popen(list(prefix) + [exe, "-c", self.conf, "--foreground"], stdout=self.log,
                                  stderr=subprocess.STDOUT)
        self.port = port
        for _ in range(100):
            try:
                socket.create_connection(("127.0.0.1", port), 0.2).close()
                return
            except OSError:
                if self.p.poll() is not None:
                    break
                time.sleep(0.05)
        raise SystemExit("fc23: it2nd did not start (log %s)" % self.log.name)

    def io_name(self):
        """The I/O path it logged at start ("I/O: io_uring")."""
        with open(self.log.name) as f:
            for line in f:
                if "I/O: " in line:
                    return line.split("I/O: ", 1)[1].split()[0]
        return "?"

    def stop(self):
        self.p.send_signal(signal.SIGTERM)
        rc = self.p.wait(20)
        self.log.close()
        if rc != 0:
            raise SystemExit("fc23: it2nd exited %d" % rc)


def load(exe, port, conns, seconds, expect, pid, split=None):
    u0, s0 = cpu_times(pid)
    r = subprocess.run([exe, "--port", str(port), "--conns", str(conns), "--seconds", str(seconds),
                        "--expect", expect], capture_output=True, text=True, timeout=seconds + 60)
    u1, s1 = cpu_times(pid)
    cpu = (u1 - u0) + (s1 - s0)
    if split is not None:  # [user s, system s] summed over the rounds
        split[0] += u1 - u0
        split[1] += s1 - s0
    out = r.stdout.split()
    if r.returncode != 0 or len(out) < 10:
        sys.stderr.write(r.stderr)
        raise SystemExit("fc23: load against port %d (%s, %d connections) failed: %s"
                         % (port, expect, conns, r.stdout.strip()))
    d = dict(zip(out[0::2], out[1::2]))
    return float(d["rate"]), int(d["requests"]), cpu, float(d["p99_us"])


def noring_check(a, tmp, n):
    """io_uring refused (a seccomp filter, as a hardened host has it):
    io = auto falls back to epoll, says so in its start line and answers
    every request; io = io_uring refuses to start, naming the reason."""
    e = It2nd(a.it2nd, tmp, free_port(), n, prefix=[a.noring], tag="auto-noring")
    try:
        _, req, _, _ = load(a.load, e.port, n, 0.5, "model", e.p.pid)
    finally:
        e.stop()
    with open(e.log.name) as f:
        log = f.read()
    if "I/O: epoll (io = auto: io_uring refused)" not in log:
        raise SystemExit("fc23 smoke: FAIL: io = auto with io_uring refused did not say it fell back to epoll:\n" + log)
    print("fc23 smoke: ok: io_uring refused (seccomp): io = auto serves on epoll, says so, %d answers correct" % req)
    conf = os.path.join(tmp, "it2nd-uring-noring.conf")
    with open(conf, "w") as f:
        f.write("[daemon]\nstate_dir = %s\nio = io_uring\n[modbus]\ntcp_listen = 127.0.0.1:%d\n"
                % (os.path.join(tmp, "state-uring-noring"), free_port()))
    r = subprocess.run([a.noring, a.it2nd, "-c", conf, "--foreground"], capture_output=True, text=True, timeout=20)
    out = r.stdout + r.stderr
    if r.returncode == 0 or "io = io_uring: the kernel refuses io_uring" not in out:
        raise SystemExit("fc23 smoke: FAIL: io = io_uring with io_uring refused: exit %d, output:\n%s"
                         % (r.returncode, out))
    print("fc23 smoke: ok: io_uring refused: io = io_uring stops the start (exit %d): %s"
          % (r.returncode, [x for x in out.splitlines() if "io_uring" in x][0].strip()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--bare", required=True)
    ap.add_argument("--load", required=True)
    ap.add_argument("--conns", default="1,8,32")
    ap.add_argument("--seconds", type=float, default=1.5)
    ap.add_argument("--rounds", type=int, default=20, help="at most this many rounds per connection count")
    # 15: the 1-connection throughput ratio is within about 1 % of its
    # target, and 5 rounds (an interval of about +-1.5 %) could not tell
    # whether it meets it; 15 narrow it to about +-0.6 % (issue 22).
    ap.add_argument("--min-rounds", type=int, default=15)
    ap.add_argument("--fine-rounds", type=int, default=40,
                    help="at most this many rounds at %d connection(s) (FINE_PRECISION)" % FINE_CONNS)
    ap.add_argument("--smoke", action="store_true")
    ap.add_argument("--noring", help="smoke: a wrapper refusing io_uring_setup (tests/fc23/noring.c)")
    ap.add_argument("--out")
    a = ap.parse_args()
    conns = [int(c) for c in a.conns.split(",")]
    if a.smoke:
        conns, a.seconds, a.rounds, a.min_rounds, a.fine_rounds = [8], 1.0, 1, 1, 1

    tmp = tempfile.mkdtemp(prefix="fc23.", dir=os.environ.get("TMPDIR"))
    bare = Bare(a.bare)
    recv = None if a.smoke else Bare(a.bare, "receive")
    d = It2nd(a.it2nd, tmp, free_port(), max(conns))
    results, slow, spread, intervals, lat, cpu_split = {}, {}, {}, {}, {}, {}
    try:
        # Warm-up, not counted: first connections, page faults, caches.
        load(a.load, bare.port, 8, 1.0, "pattern", bare.p.pid)
        load(a.load, d.port, 8, 1.0, "model", d.p.pid)
        for n in conns:
            rb, ri, rr, cb, ci, nb, ni = [], [], [], [], [], 0, 0
            sb, si = [0.0, 0.0], [0.0, 0.0]  # user, system CPU seconds over the rounds
            lb, li = [], []  # p99 latency per round (us)
            pairs = []
            # Every row's interval decides when the rounds are enough, the
            # p99 latency's too (a target at LAT_CONNS only): a row marked
            # "max rounds reached" did run to the maximum.
            def enough():
                return precise(ri, rb, thr_precision(n)) and precise(cb, ci) and precise(li, lb)
            max_rounds = a.fine_rounds if n == FINE_CONNS else a.rounds
            for r in range(max_rounds):
                if r >= a.min_rounds and enough():
                    break
                # Back to back, the order alternating: the machine's load
                # drifts, both sides see the same drift.
                for side in (("bare", "it2nd") if r % 2 == 0 else ("it2nd", "bare")):
                    if side == "bare":
                        rate, req, cpu, p99 = load(a.load, bare.port, n, a.seconds, "pattern", bare.p.pid, sb)
                        rb.append(rate)
                        lb.append(p99)
                        nb += req
                        cb.append(cpu / max(req, 1) * 1e6)
                    else:
                        rate, req, cpu, p99 = load(a.load, d.port, n, a.seconds, "model", d.p.pid, si)
                        ri.append(rate)
                        li.append(p99)
                        ni += req
                        ci.append(cpu / max(req, 1) * 1e6)
                pairs.append(round(ri[-1] / rb[-1], 3))
            if not a.smoke and not enough():
                print("fc23: %d connection(s): an interval wider than wanted after %d rounds (the maximum)"
                      % (n, len(ri)), flush=True)
                if recv:
                    rate, req, cpu, _ = load(a.load, recv.port, n, a.seconds, "pattern", recv.p.pid)
                    rr.append(rate)
            spread[n] = pairs
            cpu_split[str(n)] = {"it2nd": [round(x / max(ni, 1) * 1e6, 2) for x in si],
                                 "bare": [round(x / max(nb, 1) * 1e6, 2) for x in sb]}
            if len(ri) >= 2:
                vi, vb, lo, hi = ratio_interval(ri, rb)
                ui, ub, clo, chi = ratio_interval(ci, cb)
                pi, pb, llo, lhi = ratio_interval(li, lb)
                intervals[n] = ((lo, hi), (clo, chi), len(ri), (llo, lhi))
            else:  # --smoke: one round, no interval
                vi, vb, ui, ub, pi, pb = ri[0], rb[0], ci[0], cb[0], li[0], lb[0]
            results[n] = (vi, vb, ui, ub, ni, nb)
            lat[n] = (pi, pb)
            if rr:
                slow[n] = statistics.median(rr)
            print("fc23: %2d connection(s): it2nd %8.0f req/s (%.1f us CPU/req), bare libmodbus %8.0f req/s "
                  "(%.1f us CPU/req), ratio %.2f; p99 latency %.1f us vs %.1f us; %d + %d answers checked%s"
                  % (n, results[n][0], results[n][2], results[n][1], results[n][3],
                     results[n][0] / results[n][1], lat[n][0], lat[n][1], ni, nb,
                     "; bare with modbus_receive %.0f req/s" % slow[n] if n in slow else ""), flush=True)
    finally:
        bare.stop()
        if recv:
            recv.stop()
        d.stop()

    if a.smoke:
        # The other I/O path (daemon/loop.c): io = auto took io_uring where
        # the kernel allows it; io = epoll is checked the same way.
        e = It2nd(a.it2nd, tmp, free_port(), conns[0], io="epoll")
        try:
            _, req, _, _ = load(a.load, e.port, conns[0], a.seconds, "model", e.p.pid)
        finally:
            e.stop()
        print("fc23 smoke: every FC 23 answer correct under %d concurrent connections, io = auto (%s) and "
              "io = epoll (%d answers) (no timing checked)" % (conns[0], d.io_name(), req))
        if a.noring:
            noring_check(a, tmp, conns[0])
    rows = []
    for n in conns:
        it, bb, ci, cb, _, _ = results[n]
        iv, _, k, _ = intervals.get(n, (None, None, None, None))
        # an interval wider than the rounds aimed at came from their maximum
        rows.append(row("FC23 full query, %d connection(s): it2nd vs bare libmodbus (req/s)" % n,
                        "req/s", round(it, 1), round(bb, 1), TARGET, sense=">=", interval=iv, rounds=k,
                        precision=thr_precision(n)))
    for n in conns:
        it, bb, ci, cb, _, _ = results[n]
        _, iv, k, _ = intervals.get(n, (None, None, None, None))
        rows.append(row("FC23 server CPU per request, %d connection(s): it2nd vs bare libmodbus (us)" % n,
                        "us", round(ci, 2), round(cb, 2), CPU_TARGET, interval=iv, rounds=k))
    for n in conns:
        _, _, k, iv = intervals.get(n, (None, None, None, None))
        pi, pb = lat[n]
        rows.append(row("FC23 p99 latency, %d connection(s): it2nd vs bare libmodbus (us)" % n,
                        "us", round(pi, 1), round(pb, 1), LAT_TARGET if n == LAT_CONNS else None,
                        interval=iv, rounds=k))
    for n in conns:
        if n in slow:
            rows.append(row("FC23 full query, %d connection(s): bare libmodbus using modbus_receive "
                            "(req/s, one run)" % n, "req/s", round(slow[n], 1)))
    io_name = d.io_name()
    doc = {
        "bench": "fc23",
        "it2nd_io": io_name,
        "note": ("FC 23 (write q_u, q_w at 64; read the 108 result registers at 128) against it2nd "
                 "(host build, paper model, fsync on, io = auto: %s) and a bare libmodbus server (modbus_mapping + "
                 "modbus_reply in a poll() loop, one recv per readable client, every complete ADU framed by its "
                 "MBAP length: libmodbus used as carefully as it allows; "
                 "informational rows: the same server reading with modbus_receive) answering FC 23 of the same sizes; same load generator "
                 "(tests/fc23/fc23_load.c: N threads, one connection each, every answer checked; each connection "
                 "cycles through 256 (u, w) points over [0, 1]^2, consecutive requests differ, so it2nd evaluates "
                 "every request), "
                 "1 s warm-up of each server, then %g s per run, rounds (bare and it2nd back to back, order alternating) until the "
                 "throughput, CPU and p99 latency ratios' 95 %% intervals lie within +-5 %% "
                 "(at least %d, at most %d; at %d connection(s), where the throughput ratio lies within about 1 %% of "
                 "its target, until that ratio's interval lies within +-%g %%, at most %d rounds), geometric mean per side, ratio = "
                 "their quotient; round_ratios: each round's "
                 "it2nd / bare; client and servers share the machine's cores, other jobs too "
                 "(load_average); p99 latency: each run's 99th percentile over all connections (request sent to answer "
                 "checked, fc23_load); cpu_split: each side's [user, kernel] CPU us per request over all rounds"
                 % (io_name, a.seconds, a.min_rounds, a.rounds, FINE_CONNS, FINE_PRECISION * 100,
                    a.fine_rounds)),
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg()[0],
        "round_ratios": {str(n): spread[n] for n in conns},
        # Server CPU per request split into user and kernel time (us, from
        # /proc/PID/stat over all rounds: clock ticks, so coarse per round
        # but summed over thousands of requests).
        "cpu_split": cpu_split,
        "rows": rows,
        # An unmet target says why (tests/bench/collect.py passes it on to
        # docs/performance.md, which refuses an unexplained miss).
        "reasons": {r["name"]: REASON % (io_name, cpu_split_text(cpu_split)) for r in rows if r["met"] is False},
    }
    if a.out:
        os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
        with open(a.out, "w") as f:
            json.dump(doc, f, indent=2)
            f.write("\n")
        print("fc23: wrote %s" % a.out)
    subprocess.run(["rm", "-rf", tmp])


if __name__ == "__main__":
    main()
