#!/usr/bin/python3
"""Protocol benchmark over a paced, faulty serial line (issue 11).

Each run starts a fresh it2nd (private state directory, Modbus off) whose
[link:bench] is side A of tests/bench/proto/faultrelay, and proto_session
(the host session: HELLO, CONFIGURE, PUT all, COMMIT, QUERYs, SAMPLE) on
side B. The relay paces both directions at the baud rate and injects drop,
duplicate, reorder and corrupt faults per frame, each at the given rate, in
each direction, with fixed seeds. Every run's results are checked bit for
bit by proto_session against its own solve, and their digest must equal
the clean run's.

usage: bench_proto.py --out FILE [--smoke | --sack] [--max-rounds N] [--keep]
  full (make bench-proto): degree 7x7 with z (448 entries), 16 QUERYs,
       SAMPLE 33x33 at 921600 Bd; interleaved rounds of a clean, a 1 % and
       a 10 % run (order alternating, fault seed = round) until both
       wall-time ratios' 95 % intervals lie within +-5 % (results.py
       until_precise: at least 3, at most N = 40 rounds); durable ingest
       over one pty pair (the daemon on the slave, the session on the
       master, no relay), window 16, fsync on and off in rounds likewise
       (at most 16).
       Each ratio row keeps its interval, rounds and max_rounds_reached; a
       target is met only when the whole interval meets it; host
       re-requests are the total over all rounds. Writes FILE with a
       "rows" list.
  --smoke (make test): degree 3x3, 4 QUERYs, SAMPLE 9x9, clean and 10 %
       faults (2 seeds) at 921600 Bd, a short ingest; asserts completion and
       equal digests, never a time. Writes FILE (under build/).
  --sack (make bench-proto-sack): selective acknowledgement (protocol.md
       4.2 rule 4): v1.2 sessions with window 16 and 1 KB PUTs (19 entries),
       degree 7x7 with z, at 921600 Bd: rounds of a clean and a 10 % run
       (upload time ratio with its interval, target <= 2, as above but at
       most 80 rounds), then a
       5 clean sessions with a busy loop per core (retransmissions both ways:
       target 0). Writes FILE (bench/proto_sack.json).
"""
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "mcu"))
from results import ratio_interval, row, until_precise  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
BUILD = os.environ.get("BUILD", os.path.join(ROOT, "build"))
IT2ND = os.environ.get("IT2ND", os.path.join(BUILD, "host", "it2nd"))
RELAY = os.environ.get("FAULTRELAY", os.path.join(BUILD, "bench", "proto", "faultrelay"))
SESSION = os.environ.get("PROTO_SESSION", os.path.join(BUILD, "bench", "proto", "proto_session"))
BAUD = 921600
# PUTs in flight in the ingest runs: the daemon's window (host builds, 16).
INGEST_WINDOW = 16
# Interleaved rounds at most (--max-rounds): each ratio's 95 % interval is
# narrowed until within +-5 % (results.until_precise), or this many ran.
# The 10 % runs' wall time varies with the fault seed by about +-15 % (a
# lost frame at the end of a burst waits for a timeout), so their ratio
# needs about 40 rounds; the ingest ratio (information, no target) follows
# the disk's fsync latency and stops at INGEST_MAX_ROUNDS.
MAX_ROUNDS = 40
# The --sack run's upload ratio spreads further (1.2x to 4x per round, the
# seed deciding where a timeout falls) and lies within about 10 % of its
# target: 40 rounds gave an interval of about +-9 % whose upper end read
# 1.96 and 2.003 in two runs of the same tree (issue 22: a target that flips
# with the noise). 80 rounds narrow it to about +-6.5 %; the seeds stay the
# round numbers, so every run draws the same 80 fault patterns.
SACK_MAX_ROUNDS = 80
# Clean sessions with a busy loop per core (each about 1.5 s).
LOAD_RUNS = 5
INGEST_MAX_ROUNDS = 16


class Run:
    """One relay + daemon + session, stopped by PID."""

    def __init__(self, tmp, name, baud, fault_pct, seed, fsync=True, direct=False):
        self.d = os.path.join(tmp, name)
        os.makedirs(os.path.join(self.d, "state"))
        self.procs = []
        self.baud, self.fault, self.seed, self.fsync = baud, fault_pct, seed, fsync
        self.direct, self.master = direct, None

    def start(self):
        if self.direct:
            # one pty pair, no relay: the daemon opens the slave, the
            # session holds the master (a USB-serial adapter's view)
            self.master, slave = os.openpty()
            a = os.ttyname(slave)
            self.slave = slave
        else:
            a, b = os.path.join(self.d, "link-a"), os.path.join(self.d, "link-b")
            f = str(self.fault)
            self.relay = subprocess.Popen(
                [RELAY, "--a", a, "--b", b, "--baud", str(self.baud), "--drop", f, "--dup", f,
                 "--reorder", f, "--corrupt", f, "--seed", str(self.seed),
                 "--stats", os.path.join(self.d, "relay.json")],
                stdout=subprocess.PIPE, stderr=open(os.path.join(self.d, "relay.log"), "w"), text=True)
            self.procs.append(self.relay)
            self.relay.stdout.readline()  # slave names: both links exist now
        conf = os.path.join(self.d, "it2nd.conf")
        with open(conf, "w") as c:
            c.write("[daemon]\nstate_dir = %s\nlink_backoff_max = 1\nfsync = %s\n"
                    "[modbus]\ntcp_listen = none\n[model:1]\nn = 3\nm = 3\n"
                    "[link:bench]\ntype = serial\ndevice = %s\nbaud = %d\n"
                    % (os.path.join(self.d, "state"), "yes" if self.fsync else "no", a,
                       self.baud or 115200))
        self.daemon = subprocess.Popen([IT2ND, "-c", conf, "-f", "-v"],
                                       stdout=open(os.path.join(self.d, "daemon.log"), "w"),
                                       stderr=subprocess.STDOUT)
        self.procs.append(self.daemon)
        log = os.path.join(self.d, "daemon.log")
        for _ in range(200):  # until the link is open
            if self.daemon.poll() is not None:
                raise SystemExit("bench_proto: it2nd exited:\n" + open(log).read())
            if "bench" in open(log).read() and "open" in open(log).read():
                break
            time.sleep(0.025)
        time.sleep(0.1)
        return None if self.direct else b

    def session(self, args, timeout):
        b = self.start()
        line = ["--fd", str(self.master)] if self.direct else ["--device", b]
        # the host knows its line's baud rate as the daemon does (its RTO
        # counts from when a frame has left the line; unpaced: unknown)
        baud = ["--baud", str(self.baud)] if self.baud and not self.direct else []
        p = subprocess.run([SESSION] + line + ["--timeout", str(timeout)] + baud + args,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           timeout=timeout + 30, pass_fds=(self.master,) if self.direct else ())
        cpu = cpu_user = None
        try:  # the daemon's CPU time (user + system) so far, start-up included
            f = open("/proc/%d/stat" % self.daemon.pid).read().rsplit(")", 1)[1].split()
            cpu = (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
            cpu_user = int(f[11]) / os.sysconf("SC_CLK_TCK")
        except (OSError, ValueError, IndexError):
            pass
        self.stop()
        open(os.path.join(self.d, "session.err"), "w").write(p.stderr)
        try:
            res = json.loads(p.stdout)
        except ValueError:
            raise SystemExit("bench_proto: session printed no result (exit %d): %s%s"
                             % (p.returncode, p.stdout, p.stderr))
        res["exit"] = p.returncode
        res["daemon_cpu_s"] = cpu
        res["daemon_cpu_user_s"] = cpu_user
        try:
            res["relay"] = json.load(open(os.path.join(self.d, "relay.json")))
        except (OSError, ValueError):
            res["relay"] = None
        res["fault_pct"], res["seed"], res["baud"] = self.fault, self.seed, self.baud
        return res

    def stop(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        self.procs = []
        if self.master is not None:
            os.close(self.master)
            os.close(self.slave)
            self.master = None


# Why a target can be missed, by a substring of the row's name: what the
# bench's own logs show about where the time goes.
REASONS = {
    "faults per direction vs clean":
        "each lost frame, ACK or GAP at the end of a burst (and of each "
        "stop-and-wait exchange: HELLO, CONFIGURE, COMMIT, the last QUERY, "
        "SAMPLE) waits for a timeout of 32 ms after it has left the line, "
        "and at 10 % drop + 10 % corruption per direction a round trip fails "
        "about one time in three, so repeated losses of one frame stack up "
        "(backoff from the fourth retransmission); retransmission counts "
        "per run in bench/proto_loss.json",
    "host re-requests":
        "a response run the daemon gave up on, or a request refused while busy, "
        "is sent again by the host",
    "durable ingest":
        "below 20 000 only on an overloaded machine: with window 16 the "
        "daemon's group commit releases 16 ACKs at once and the session "
        "refills the window at once (about 42 000 entries/s on the 2-core "
        "test machine, window 4: about 30 000); daemon CPU per entry is in "
        "daemon_cpu_us_per_entry of bench/proto_loss.json",
}


# Why a row of the --sack run can miss its target (what its traces show).
REASONS_SACK = {
    "under CPU load":
        "the pipeline stops for longer than the link's rules cover: with the "
        "CPUs loaded, traces show 40-100 ms in which nothing reaches the "
        "session (the daemon or the relay did not run). The timers restart "
        "on every answer (in-order delivery), only the oldest unanswered "
        "frame times out, silence after newer frames waits 4 RTO (128 ms) "
        "before a probe, a RCVD'd frame waits while a later ACK can name it, "
        "a half-received answer holds the timer (docs/protocol.md 4.2 rules 3 "
        "and 4c): a stall longer than that, or a lone frame (no newer one to "
        "tell a stall from a loss) held longer than the adaptive RTO, still "
        "costs one retransmission (harmless: the receiver's history); "
        "loadavg_at_end shows other jobs' load",
    "vs clean":
        "each loss at the end of a burst (the last PUTs, COMMIT) waits for a "
        "timeout, and a deferred answer whose ACK is lost for twice the "
        "deferral seen lately; the figure moves with the machine's load",
}


def busy_loops():
    """One busy process per core (CPU load for the spurious-retransmission
    run); the caller kills them."""
    return [subprocess.Popen(["/bin/sh", "-c", "while :; do :; done"]) for _ in range(os.cpu_count() or 2)]


def injected(rel):
    """Faults the relay injected, both directions, every kind."""
    return sum((rel or {}).get(d, {}).get(k, 0) for d in ("a_to_b", "b_to_a")
               for k in ("dropped", "duplicated", "reordered", "corrupted"))


def every_kind(rel):
    """True when the relay injected every fault kind in both directions."""
    return all((rel or {}).get(d, {}).get(k, 0) > 0 for d in ("a_to_b", "b_to_a")
               for k in ("dropped", "duplicated", "reordered", "corrupted"))


def interval_row(name, unit, values, baselines, target, rounds, sense="<=", digits=3):
    """A ratio row from paired rounds (values[i] measured beside
    baselines[i]): geometric means, their 95 % interval, the rounds and
    whether they stopped at their maximum with the interval still wider
    than +-5 % (results.row() derives the flag from the interval: the
    rounds stop early only once it is that narrow)."""
    v, b, lo, hi = ratio_interval(values, baselines)
    return row(name, unit, round(v, digits) if digits else round(v), round(b, digits) if digits else round(b),
               target, sense=sense, interval=[lo, hi], rounds=rounds)


def sack_main(out, keep, max_rounds):
    """Window 16 v1.2 sessions: upload under 10 % faults vs clean in
    interleaved rounds (a new fault seed per round), and the
    retransmissions of a clean run under CPU load (docs/protocol.md 4.2)."""
    tmp = tempfile.mkdtemp(prefix="it2n-protobench-sack.")
    failures = []
    sess = ["--degree", "7x7", "--queries", "16", "--sample", "33", "--window", "16", "--version", "3"]
    runs = {}
    clean, f10 = [], []

    def one(name, pct, seed, load):
        hogs = busy_loops() if load else []
        try:
            r = Run(tmp, name, BAUD, pct, seed).session(sess, 600)
        finally:
            for h in hogs:
                h.kill()
                h.wait()
        runs[name] = r
        # in a clean run every retransmission is spurious: ours (tx_retx) and
        # the daemon's (duplicates it sent us: rx_dup)
        r["spurious"] = r["link"]["tx_retx"] + r["link"]["rx_dup"] if not pct else None
        r["cpu_load"] = load
        print("bench-proto-sack: %-16s faults %3s%%  upload %7.3f s  wall %7.3f s  retx %d (fast %d)  "
              "dup rx %d  in flight %d  exit %d" % (name, pct, r["upload_s"], r["wall_s"], r["link"]["tx_retx"],
                                                   r["link"]["tx_fast_retx"], r["link"]["rx_dup"],
                                                   r["max_in_flight"], r["exit"]), flush=True)
        if r["exit"] != 0 or not r["ok"]:
            failures.append("%s: session failed (exit %d); logs in %s" % (name, r["exit"], os.path.join(tmp, name)))
        if r["max_in_flight"] != 16:
            failures.append("%s: at most %d PUTs in flight, want 16" % (name, r["max_in_flight"]))
        if pct and not every_kind(r["relay"]):
            failures.append("%s: the relay did not inject every fault in both directions: %s" % (name, r["relay"]))
        return r

    def one_round(k):
        # clean and faulty back to back, the order alternating: both see
        # the same drift of the machine's load; a new fault seed per round
        order = [("r%d-clean" % (k + 1), 0), ("r%d-f10-s%d" % (k + 1, k + 1), 10)]
        for name, pct in (order if k % 2 == 0 else order[::-1]):
            r = one(name, pct, k + 1, False)
            (f10 if pct else clean).append(r["upload_s"])

    rounds, capped = until_precise(one_round, lambda: [(f10, clean)], max_rounds)
    # Several sessions under load: the first stall of a session comes
    # before its round trips show the load; one run's 0 could be luck.
    loads = [one("clean-load-%d" % (k + 1), 0, k + 1, True) for k in range(LOAD_RUNS)]
    ref = runs["r1-clean"]["digest"]
    for n, r in runs.items():
        if r["digest"] != ref:
            failures.append("%s: results differ from the clean run" % n)
    res = {"what": "v1.2 sessions, window 16, 1 KB PUTs (19 entries), it2nd over a pty relay paced at %d Bd; "
                   "10 %% faults = drop, duplicate, reorder and corrupt each at 10 %% per frame, each direction; "
                   "rounds of a clean and a 10 %% run back to back (order alternating, fault seed = round) until "
                   "the upload ratio's 95 %% interval lies within +-5 %% (at least 3, at most %d rounds); "
                   "ratio = geometric mean of the faulty uploads over the clean ones; the load runs have a busy "
                   "loop on every core (%d sessions, after the rounds)" % (BAUD, max_rounds, LOAD_RUNS),
           "rounds": rounds, "max_rounds": max_rounds, "max_rounds_reached": capped,
           "loadavg_at_end": os.getloadavg(), "cpus": os.cpu_count(), "runs": runs, "failures": failures,
           "rows": [
               interval_row("proto upload, window 16, 1 KB PUTs, 10 % faults per direction vs clean, 921600 Bd "
                            "(selective acknowledgement)", "s", f10, clean, 2.0, rounds),
               row("proto clean sessions under CPU load (a busy loop per core, %d sessions): "
                   "retransmissions both ways" % LOAD_RUNS,
                   "frames", sum(r["spurious"] for r in loads), target=0),
           ]}
    res["reasons"] = {r["name"]: REASONS_SACK[k] for r in res["rows"] if r["met"] is False
                      for k in REASONS_SACK if k in r["name"]}
    with open(out, "w") as f:
        json.dump(res, f, indent=2, sort_keys=True)
        f.write("\n")
    print("bench-proto-sack: %d rounds%s; results in %s"
          % (rounds, " (the maximum, interval wider than +-5 %)" if capped else "", out))
    for x in failures:
        print("bench-proto-sack: FAIL: " + x, file=sys.stderr)
    if failures or keep:
        print("bench-proto-sack: logs kept in " + tmp, file=sys.stderr)
    else:
        shutil.rmtree(tmp)
    return 1 if failures else 0


def check_session(name, r, pct, failures, tmp):
    """A run's own checks (the relay's faults and pacing, the session's
    results); every fault kind is required at 10 % (the 1 % runs are
    checked together: a single small run may draw none)."""
    rel = r["relay"] or {}
    if pct >= 5 and not every_kind(rel):
        failures.append("%s: the relay did not inject every fault in both directions: %s" % (name, rel))
    if not pct and any(rel.get(d, {}).get("bytes_in") != rel.get(d, {}).get("bytes_out")
                       for d in ("a_to_b", "b_to_a")):
        failures.append("%s: the clean relay lost or added bytes: %s" % (name, rel))
    if rel:
        # share of the wall time the busier line was sending (pacing sanity: <= 1)
        r["line_busy"] = round(max(rel[d]["bytes_out"] for d in ("a_to_b", "b_to_a")) * 10.0 / BAUD
                               / r["wall_s"], 3) if r["wall_s"] else None
        if r["line_busy"] and r["line_busy"] > 1.02:
            failures.append("%s: more bytes than the line can carry at %d Bd: pacing broken" % (name, BAUD))
    if r["exit"] != 0 or not r["ok"]:
        failures.append("%s: session failed (exit %d, mismatches %d, refused %d); logs in %s"
                        % (name, r["exit"], r["mismatches"], r["refused"], os.path.join(tmp, name)))


def ingest_run(tmp, name, fs, rounds, limit, failures):
    r = Run(tmp, name, 0, 0, 1, fsync=fs, direct=True).session(
        ["--degree", "7x7", "--ingest", str(rounds), "--window", str(INGEST_WINDOW)], limit)
    if r["daemon_cpu_s"] and r["entries_acked"]:
        r["daemon_cpu_us_per_entry"] = round(r["daemon_cpu_s"] * 1e6 / r["entries_acked"], 1)
    print("bench-proto: %s  %d entries in %.3f s: %.0f entries/s, at most %d PUTs in flight "
          "(daemon window %d), daemon CPU %s s, exit %d"
          % (name, r["entries_acked"], r["put_s"], r["entries_per_s"], r["max_in_flight"],
             r["daemon_window"], r["daemon_cpu_s"], r["exit"]), flush=True)
    if r["exit"] != 0 or r["entries_acked"] != r["entries"]:
        failures.append("%s: ingest failed (exit %d, %d of %d entries ACKed)"
                        % (name, r["exit"], r["entries_acked"], r["entries"]))
    if r["daemon_window"] != INGEST_WINDOW or r["max_in_flight"] != INGEST_WINDOW:
        failures.append("%s: window not negotiated: daemon announced %d, at most %d PUTs in flight, "
                        "want %d" % (name, r["daemon_window"], r["max_in_flight"], INGEST_WINDOW))
    return r


def main():
    args = sys.argv[1:]
    out = args[args.index("--out") + 1]
    given = int(args[args.index("--max-rounds") + 1]) if "--max-rounds" in args else None
    if "--sack" in args:
        return sack_main(out, "--keep" in args, given or SACK_MAX_ROUNDS)
    max_rounds = given or MAX_ROUNDS
    smoke = "--smoke" in args
    tmp = tempfile.mkdtemp(prefix="it2n-protobench.")
    failures = []
    runs, ingest = {}, {}
    clean, f1, f10, on, off = [], [], [], [], []

    def session(name, pct, seed):
        r = Run(tmp, name, BAUD, pct, seed).session(sess, limit)
        runs[name] = r
        print("bench-proto: %-10s faults %4s%%  wall %7.3f s  host re-requests %d  retx %d  exit %d  digest %s"
              % (name, pct, r["wall_s"], r["host_rerequests"], r["link"]["tx_retx"], r["exit"], r["digest"]),
              flush=True)
        check_session(name, r, pct, failures, tmp)
        return r

    if smoke:
        sess = ["--degree", "3x3", "--queries", "4", "--sample", "9"]
        limit = 120
        # seeds whose fault streams hold every kind within the first 16 frames
        # of each direction (the small session has about 30 per direction)
        for name, pct, seed in (("clean", 0, 1), ("f10-s44", 10, 44), ("f10-s49", 10, 49)):
            session(name, pct, seed)
        ingest_rounds = 5
        for fs in (True, False):
            name = "ingest-fsync-%s-1" % ("on" if fs else "off")
            ingest[name] = ingest_run(tmp, name, fs, ingest_rounds, limit, failures)
        rounds = ingest_reps = 1
        capped = capped_ingest = None
    else:
        sess = ["--degree", "7x7", "--queries", "16", "--sample", "33"]
        limit = 600

        def one_round(k):
            # clean, 1 % and 10 % back to back, the order alternating (both
            # sides of each ratio see the same drift of the machine's load);
            # a new fault seed per round
            order = [("r%d-clean" % (k + 1), 0, clean), ("r%d-f1-s%d" % (k + 1, k + 1), 1, f1),
                     ("r%d-f10-s%d" % (k + 1, k + 1), 10, f10)]
            for name, pct, into in (order if k % 2 == 0 else order[::-1]):
                into.append(session(name, pct, k + 1)["wall_s"])

        rounds, capped = until_precise(one_round, lambda: [(f1, clean), (f10, clean)], max_rounds)
        if not sum(injected(r["relay"]) for n, r in runs.items() if "-f1-" in n):
            failures.append("the relay injected no fault in any 1 % run")
        ingest_rounds = 40

        def ingest_round(k):  # fsync on and off back to back, the order alternating
            for fs in ((True, False) if k % 2 == 0 else (False, True)):
                name = "ingest-fsync-%s-%d" % ("on" if fs else "off", k + 1)
                r = ingest[name] = ingest_run(tmp, name, fs, ingest_rounds, limit, failures)
                (on if fs else off).append(r["entries_per_s"])

        ingest_reps, capped_ingest = until_precise(ingest_round, lambda: [(off, on)],
                                                   min(max_rounds, INGEST_MAX_ROUNDS))
    first = runs[next(iter(runs))]
    ref = first["digest"]
    for n, r in runs.items():
        if r["digest"] != ref:
            failures.append("%s: results differ from the clean run (digest %s, clean %s)" % (n, r["digest"], ref))

    res = {"what": "it2nd link session over a pty relay paced at %d Bd (10 bits/byte), frame faults "
                   "(drop, duplicate, reorder, corrupt, each at the rate, each direction, fault seed = round)" % BAUD,
           "method": "rounds of a clean, a 1 %% and a 10 %% run back to back (order alternating) until both "
                     "wall-time ratios' 95 %% intervals lie within +-5 %% (at least 3, at most %d rounds); "
                     "ratio = geometric mean of the faulty runs' wall times over the clean ones' "
                     "(results.py ratio_interval); the ingest likewise, fsync on and off (at most %d)"
                     % (max_rounds, min(max_rounds, INGEST_MAX_ROUNDS)),
           "rounds": rounds, "ingest_rounds": ingest_reps, "max_rounds": max_rounds,
           "max_rounds_reached": capped, "ingest_max_rounds_reached": capped_ingest,
           "session": {"degree": first["degree"], "entries": first["entries"],
                       "queries": first["queries"], "sample": first["sample"],
                       "z": True, "queries_pipelined": "within the window (4)",
                       "rto": "host and daemon: 20 ms + one maximum frame at the baud (32 ms at 921600), "
                              "counted from when the frame has left the line (protocol.md 4.2 rule 3)",
                       "host_rerequest_after_ms": 3000},
           "ingest_conditions": "one pty pair, no relay (the daemon's [link:] on the slave, the session on the "
                                "master), degree 7x7 with z (448 entries), the grid PUT %d times with REPLACE (the "
                                "first round completes and solves the model, the others update it), 19 entries per "
                                "PUT, window %d (negotiated in HELLO); entries/s from the first PUT to the last "
                                "PUT's ACK (ACK after the WAL's fdatasync when fsync = yes); state directory under "
                                "%s; %d rounds of fsync on and off back to back (order alternating)"
                                % (ingest_rounds, INGEST_WINDOW, tempfile.gettempdir(), ingest_reps),
           "loadavg_at_end": os.getloadavg(), "cpus": os.cpu_count(),
           "runs": runs, "ingest": ingest, "smoke": smoke}
    if not smoke:
        rr = sum(r["host_rerequests"] for n, r in runs.items() if "-f" in n)
        res["rows"] = [
            interval_row("proto session, 10 % faults per direction vs clean, 921600 Bd (wall time)", "s",
                         f10, clean, 3.0, rounds),
            interval_row("proto session, 1 % faults per direction vs clean, 921600 Bd (wall time)", "s",
                         f1, clean, 1.3, rounds),
            row("proto session host re-requests, 1 % and 10 % faults (total over all rounds)", "requests", rr,
                target=0),
            row("durable ingest over a pty, fsync on (PUT entries/s, 7x7 grid, REPLACE; median of the rounds)",
                "entries/s", round(statistics.median(on)), target=20000, sense=">="),
            interval_row("durable ingest over a pty, fsync off vs on (PUT entries/s)", "entries/s", off, on, None,
                         ingest_reps, digits=0),
        ]
        # An unmet target says why (tests/bench/collect.py passes this on to
        # docs/performance.md, which refuses an unexplained miss).
        res["reasons"] = {r["name"]: REASONS[k] for r in res["rows"] if r["met"] is False
                          for k in REASONS if k in r["name"]}
    res["failures"] = failures
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, "w") as f:
        json.dump(res, f, indent=2, sort_keys=True)
        f.write("\n")
    if not smoke:
        print("bench-proto: %d session rounds%s, %d ingest rounds%s"
              % (rounds, " (the maximum, an interval wider than +-5 %)" if capped else "",
                 ingest_reps, " (the maximum, interval wider than +-5 %)" if capped_ingest else ""))
    print("bench-proto: results in %s" % out)
    if failures:
        for x in failures:
            print("bench-proto: FAIL: " + x, file=sys.stderr)
        print("bench-proto: logs kept in " + tmp, file=sys.stderr)
        return 1
    if "--keep" not in args:
        shutil.rmtree(tmp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
