#!/usr/bin/python3
"""slowdisk_test.py -- "reads never wait for the disk" (issue 8 item 6),
tested against the real it2nd process on loopback TCP.

  slowdisk_test.py --it2nd BIN --failio failio.so [--delay-ms 500]
                   [--seconds 20] [--out bench/daemon_slowdisk.json]

The daemon runs with failio.so in slow-disk mode (IT2N_FAILIO_DELAY_MS: every
fsync and fdatasync sleeps first) and snapshot_interval 2 (checkpoints, four
delayed fsyncs each, run all the time too). Meanwhile:

  * two writer clients write the data points D(0,0) and D(3,3) of unit 1
    continuously (FC 16 on the upload block, T = 1, 2, 3, ...; the next write
    as soon as the previous one is answered) and record every answer;
  * a read-only client polls FC 04 back to back (the status block, and every
    tenth request the sample grid node 0 = T of D(0,0)) and records every
    request's latency.

Checks: the read-only client's median latency <= 2 ms and p99 <= 20 ms (the
issue's targets; --median-ms / --p99-ms), no read failed, the T it sees never
goes back (no change is shown and then undone), every write acknowledged
(none refused: a slow disk is not an I/O error) and each acknowledgement
came after at least one delayed fdatasync. Then kill -9 while the writer is
still writing, restart without the shim: T is the last acknowledged value
or the one write in flight at the kill, and the generation moved by exactly
the acknowledged writes (+1 for that one), as e2e_durability.sh checks.
A baseline run without the delay is measured for comparison (and SIGTERM
given while its writers write must exit 0). Last, slow and failing: fdatasync
delayed 200 ms and failing with EIO for 1.5 s (failio.so's flag file) under
the two writers: every refusal is exception 04, a failed batch takes the one
gathered behind it along, writes are accepted again within 5 s of the disk
coming back (recovery checkpoint), and after kill -9 the restart holds
exactly the acknowledged writes. Figures go to --out (JSON). Exit status 0
when every check passed.
"""
import argparse
import json
import os
import signal
import socket
import statistics
import struct
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from conn_test import Daemon, connect, read_regs, write_regs  # noqa: E402
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

R = report.Report("slowdisk")
ok, fail, check = R.ok, R.fail, R.check
FAILS = R.fails


def conf(state, port, snap):
    return ("[daemon]\nstate_dir = %s\nsnapshot_interval = %d\n"
            "[modbus]\ntcp_listen = 127.0.0.1:%d\n"
            "[model:1]\nunit_id = 1\npreload = paper\n" % (state, snap, port))


# The points the writers change: the corners D(0,0) and D(3,3) of the paper
# data (x, y as there, i32 x100), and the sample-grid register holding their
# T (grid 5x5: nodes (0,0) and (4,4)).
POINTS = [
    ((0, 0), (-1700, 1700), 1024),
    ((3, 3), (1700, -1700), 1024 + (4 * 5 + 4) * 3),
]


def i32(v):
    v &= 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


def upload(k, t):
    (i, j), (x, y), _ = POINTS[k]
    # i j fp(D), x, y, z 0, T I F (as dur_writer.py)
    return [i, j, 3] + i32(x) + i32(y) + [0, 0, t, 7000, 2000]


def generation(s):
    r = read_regs(s, 1, 7, 2)
    return r[0] << 16 | r[1]


class Writer(threading.Thread):
    def __init__(self, port, k, first):
        super().__init__(daemon=True)
        self.port, self.k, self.value = port, k, first
        self.acked, self.refused, self.errors = [], [], []
        self.ack_ms = []
        self.sent = None
        self.stop = False

    def run(self):
        try:
            s = connect(self.port, timeout=10)
            tid = 0
            while not self.stop:
                tid = (tid + 1) & 0xFFFF
                self.sent = self.value
                t0 = time.perf_counter()
                r = write_regs(s, 1, 40, upload(self.k, self.value), tid)
                dt = (time.perf_counter() - t0) * 1000
                if r == "ok":
                    self.acked.append(self.value)
                    self.ack_ms.append(dt)
                else:
                    self.refused.append((self.value, r))
                    time.sleep(0.01)  # refused at once: do not spin
                self.value = self.value % 9999 + 1
        except (OSError, ConnectionError, ValueError) as e:
            self.errors.append(str(e))


class Reader(threading.Thread):
    def __init__(self, port):
        super().__init__(daemon=True)
        self.port = port
        self.lat = []
        self.errors = []
        self.t_seen = []
        self.stop = False

    def run(self):
        s = connect(self.port, timeout=10)
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        tid = 0
        while not self.stop:
            tid = (tid + 1) & 0xFFFF
            grid = tid % 10 == 0
            t0 = time.perf_counter()
            try:
                r = read_regs(s, 1, 1024 if grid else 0, 3 if grid else 27, tid)
            except (OSError, ConnectionError, ValueError) as e:
                self.errors.append(str(e))
                return
            self.lat.append((time.perf_counter() - t0) * 1000)
            if r[0] == "exc":
                self.errors.append("exception %d" % r[1])
            elif grid:
                self.t_seen.append(r[0])


def pct(v, p):
    v = sorted(v)
    return v[min(len(v) - 1, int(p / 100.0 * len(v)))]


def summary(lat):
    return {
        "samples": len(lat),
        "median_ms": round(statistics.median(lat), 3),
        "p90_ms": round(pct(lat, 90), 3),
        "p99_ms": round(pct(lat, 99), 3),
        "p999_ms": round(pct(lat, 99.9), 3),
        "max_ms": round(max(lat), 3),
    }


def run_load(args, tmp, name, delay_ms, seconds, kill):
    """Start the daemon (delay_ms: slow-disk shim), a writer and a reader for
    `seconds`; kill -9 at the end if `kill`, else SIGTERM. Returns the
    figures and the writer/reader objects."""
    port = free_port()
    state = os.path.join(tmp, name + "-state")
    d = Daemon(args.it2nd, tmp, name)
    env_prefix = ["env", "LD_PRELOAD=" + args.failio, "IT2N_FAILIO_DELAY_MS=%d" % delay_ms]
    d.start(conf(state, port, 2), " ready (", prefix=env_prefix)
    s = connect(port)
    g0 = generation(s)
    s.close()
    ws = [Writer(port, k, 1) for k in range(len(POINTS))]
    rd = Reader(port)
    for w in ws:
        w.start()
    time.sleep(0.2)
    rd.start()
    time.sleep(seconds)
    rd.stop = True
    rd.join(10)
    if kill:
        d.proc.send_signal(signal.SIGKILL)
        d.proc.wait()
        d.proc = None
    else:
        # SIGTERM while the writers are writing: the stop drains the batch
        # in flight and the gathered one, answers them, and exits 0
        # (sanitizer builds: a leak or error report makes it non-zero).
        rc = d.stop()
        check(rc == 0, "%s: SIGTERM with writes in flight: exit status 0" % name, "exit %s" % rc)
    for w in ws:
        w.stop = True
        w.join(15)
    return d, port, state, g0, ws, rd


def run_fault(args, tmp, figs):
    """Slow and failing: fdatasync delayed and, for a while, failing with EIO
    (failio.so's flag file) while two clients write. A failed batch takes
    the batch gathered behind it along (both refused with 04, store
    degraded, recovery checkpoint once the disk is back); kill -9 at the
    end and the replay check: exactly the acknowledged writes."""
    port = free_port()
    state = os.path.join(tmp, "fault-state")
    flag = os.path.join(tmp, "fault-flag")
    d = Daemon(args.it2nd, tmp, "fault")
    d.start(conf(state, port, 3600), " ready (",
            prefix=["env", "LD_PRELOAD=" + args.failio, "IT2N_FAILIO_DELAY_MS=200",
                    "IT2N_FAILIO_FLAG=" + flag, "IT2N_FAILIO_CALL=fdatasync", "IT2N_FAILIO_PATH=/wal"])
    s = connect(port)
    g0 = generation(s)
    s.close()
    ws = [Writer(port, k, 1) for k in range(len(POINTS))]
    for w in ws:
        w.start()
    time.sleep(1.5)
    n_before = sum(len(w.acked) for w in ws)
    open(flag, "w").close()
    time.sleep(1.5)
    os.unlink(flag)
    t_back = time.time()
    n_at_back = sum(len(w.acked) for w in ws)
    while time.time() - t_back < 10 and sum(len(w.acked) for w in ws) < n_at_back + 4:
        time.sleep(0.05)
    recovered_s = time.time() - t_back
    time.sleep(0.5)
    d.proc.send_signal(signal.SIGKILL)
    d.proc.wait()
    d.proc = None
    for w in ws:
        w.stop = True
        w.join(15)
    log = d.logtext()
    refused = [r for w in ws for r in w.refused]
    acked = [a for w in ws for a in w.acked]
    d2 = Daemon(args.it2nd, tmp, "fault-replay")
    d2.start(conf(state, port, 3600), " ready (")
    s = connect(port)
    g1 = generation(s)
    after = [read_regs(s, 1, reg, 1)[0] for _, _, reg in POINTS]
    s.close()
    d2.stop()
    good, extra = True, 0
    for w, t in zip(ws, after):
        last = w.acked[-1] if w.acked else None
        if t != last and t == w.sent:
            extra += 1
        elif t != last:
            good = False
    good = good and g1 - g0 == len(acked) + extra
    with_gathered = log.count("(with the ones gathered meanwhile)")
    figs["slow_and_failing"] = {
        "delay_ms": 200, "fail_s": 1.5, "acked": len(acked), "acked_before_fault": n_before,
        "refused": len(refused), "failed_batches_with_a_gathered_one": with_gathered,
        "writes_accepted_again_after_s": round(recovered_s, 2), "generations_moved": g1 - g0,
    }
    check(refused and all(r[1] == ("exc", 4) for r in refused),
          "slow + failing fdatasync: %d writes refused, all with exception 04 (%d failed batch(es) took a "
          "gathered batch along)" % (len(refused), with_gathered), "%r" % refused[:3])
    check("store degraded" in log and "writes accepted again" in log and recovered_s < 5,
          "degraded, then a checkpoint once the disk is back: writes accepted again after %.1f s" % recovered_s)
    check(good, "kill -9 + restart: exactly the acknowledged writes (T %s, last acknowledged %s; generation +%d for "
          "%d acknowledged + %d in flight found durable)"
          % (after, [w.acked[-1] if w.acked else None for w in ws], g1 - g0, len(acked), extra))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--failio", required=True)
    ap.add_argument("--delay-ms", type=int, default=500)
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("--baseline-seconds", type=float, default=5)
    ap.add_argument("--median-ms", type=float, default=2.0)
    ap.add_argument("--p99-ms", type=float, default=20.0)
    ap.add_argument("--out")
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="it2nd-slowdisk.")
    figs = {"conditions": {
        "cpus": os.cpu_count(),
        "loadavg_1min": round(os.getloadavg()[0], 2),
        "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "note": ("it2nd (host build) on loopback TCP; failio.so delays every fsync/fdatasync by delay_ms; "
                 "snapshot_interval 2; two writer clients (FC16 on the corners D(0,0) and D(3,3) of unit 1, next write on each answer) and one read-only "
                 "client (FC04 back to back: status block, every tenth the grid node); latency measured in the "
                 "Python client (send to complete reply)"),
    }}

    # Baseline: no delay.
    d, port, state, g0, ws, rd = run_load(args, tmp, "baseline", 0, args.baseline_seconds, kill=False)
    if rd.lat:
        figs["baseline_no_delay"] = dict(summary(rd.lat), writes_acked=sum(len(w.acked) for w in ws),
                                         seconds=args.baseline_seconds)

    # The slow disk.
    d, port, state, g0, ws, rd = run_load(args, tmp, "slow", args.delay_ms, args.seconds, kill=True)
    acked = [a for w in ws for a in w.acked]
    ack_ms = [a for w in ws for a in w.ack_ms]
    refused = [a for w in ws for a in w.refused]
    fig = summary(rd.lat) if rd.lat else {"samples": 0}
    fig.update({
        "delay_ms": args.delay_ms,
        "seconds": args.seconds,
        "writers": len(ws),
        "writes_acked": len(acked),
        "writes_refused": len(refused),
        "write_ack_median_ms": round(statistics.median(ack_ms), 1) if ack_ms else None,
        "write_ack_max_ms": round(max(ack_ms), 1) if ack_ms else None,
    })
    figs["slow_disk"] = fig
    n = len(rd.lat)
    check(n >= 5000, "read-only client: %d FC04 requests answered in %.0f s" % (n, args.seconds))
    check(not rd.errors, "read-only client: no failed request", "; ".join(rd.errors[:3]))
    if n:
        check(fig["median_ms"] <= args.median_ms,
              "FC04 median latency %.3f ms <= %.1f ms with fdatasync delayed %d ms"
              % (fig["median_ms"], args.median_ms, args.delay_ms))
        check(fig["p99_ms"] <= args.p99_ms,
              "FC04 p99 latency %.3f ms <= %.1f ms (p99.9 %.3f, max %.3f)"
              % (fig["p99_ms"], args.p99_ms, fig["p999_ms"], fig["max_ms"]))
    # (each writer's connection ends with the kill -9: that error is expected)
    check(all(len(w.acked) >= 3 for w in ws) and not refused and all(len(w.errors) <= 1 for w in ws),
          "%d writers: %d writes acknowledged, none refused (median ack %s ms, max %s ms)"
          % (len(ws), len(acked), fig["write_ack_median_ms"], fig["write_ack_max_ms"]),
          "refused %r, errors %r" % (refused[:3], [w.errors for w in ws]))
    check(ack_ms and min(ack_ms) >= args.delay_ms * 0.9,
          "every acknowledgement came after a delayed fdatasync (fastest %.1f ms)"
          % (min(ack_ms) if ack_ms else 0))
    seen = list(rd.t_seen)
    while seen and seen[0] == 4000:  # the paper's T before the first write
        seen.pop(0)
    back = [(a, b) for a, b in zip(seen, seen[1:]) if b < a]
    check(not back, "reader never saw T go back (%d grid reads)" % len(rd.t_seen), "%r" % back[:3])

    # kill -9 happened with the writers mid-write: restart without the shim.
    d2 = Daemon(args.it2nd, tmp, "replay")
    d2.start(conf(state, port, 3600), " ready (")
    s = connect(port)
    g1 = generation(s)
    after = [read_regs(s, 1, reg, 1)[0] for _, _, reg in POINTS]
    s.close()
    rc = d2.stop()
    check(rc == 0, "restarted daemon: SIGTERM exit status 0", "exit %s" % rc)
    good, extra, rep = True, 0, []
    for w, t in zip(ws, after):
        last = w.acked[-1] if w.acked else None
        if t != last and t == w.sent:
            extra += 1  # the write in flight at the kill was durable, not yet acknowledged
        elif t != last:
            good = False
        rep.append({"acked": len(w.acked), "last_acked": last, "in_flight_at_kill": w.sent, "t_after_restart": t})
    good = good and g1 - g0 == len(acked) + extra
    figs["slow_disk"]["replay"] = {"writers": rep, "generations_moved": g1 - g0}
    check(good, "kill -9 during writes + restart: every acknowledged write survived "
          "(T %s, last acknowledged %s, in flight %s; generation +%d for %d acknowledged + %d in flight found durable)"
          % (after, [r["last_acked"] for r in rep], [w.sent for w in ws], g1 - g0, len(acked), extra))

    run_fault(args, tmp, figs)

    if args.out:
        old = {}
        try:
            with open(args.out) as f:
                old = json.load(f)
        except (OSError, ValueError):
            pass
        old.update(figs)
        with open(args.out, "w") as f:
            json.dump(old, f, indent=2, sort_keys=True)
            f.write("\n")
    R.tidy(tmp)
    sys.exit(R.finish())


if __name__ == "__main__":
    main()
