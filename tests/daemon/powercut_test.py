#!/usr/bin/python3
"""powercut_test.py -- power cuts under the real it2nd (issue 20 item 5).

  powercut_test.py --it2nd BIN --instrument BIN --shim powercut.so
                   [--cycles 32] [--seed S] [--out FILE] [--keep]

The fault layer is tests/daemon/powercut.c, an LD_PRELOAD shim in the
daemon that keeps, beside the state directory, the image a power cut would
leave: each file's content as of its last fsync/fdatasync, the directory's
entries as of its last fsync (creates, renames and unlinks since are undone;
optionally a prefix of them kept, as a journal might), the directory itself
only once its parent was fsynced after the mkdir. A cut is SIGKILL (from
here at a random moment, or by the shim itself at a chosen event), then
tests/daemon/powercut_image.py replaces the state directory by that image,
optionally tearing the last unsynced write (a random part of the bytes
written after the durable content kept), and the daemon restarts on it.

Load, on one daemon: two Modbus TCP writers (units 1 and 2, the paper data
preloaded; each operation an FC 23 upload of one data point, new T/I/F,
with the status block read back) and instrument sessions on a serial (pty)
link (unit 7: CONFIGURE, PUT batches, COMMIT of a random data set, half with
link noise; tests/sim/instrument).

Cycles (--cycles, default 32): start (sometimes with a cut inside start-up
recovery: the shim kills the daemon at its Nth state-directory event, while
it keeps the torn tail of the WAL, truncates the WAL, removes temporary
files ...; then roll back and start again), check, load, cut: a random
moment, inside a checkpoint (before/after fsync of snapshot.tmp, after
its rename, before/after the directory fsync, in the new WAL's creation), or
between a WAL write and its fdatasync (an unsynced tail to tear).
The first cycle starts on a state directory that does not exist yet and is
cut with the strict namespace: the directory's creation must have been made
durable (store.c fsyncs its parent).

Check after every restart (replay-compare): each Modbus writer's
operations since the last check are all acknowledged but at most the last
(in flight at the cut); points received (status registers 13-14) must have
advanced by k, at least the number acknowledged (else: LOST) and at most the
number sent (else: FABRICATED). A link session's effect must be a prefix of
it (CONFIGURE, the first k entries, COMMIT) with k at least the entries
ACKed. The operations found applied are then replayed into a reference
it2nd (fsync off, never cut) and both daemons' models compared register for
register (status, sample grids, control nets, query results): any other
difference is a fabricated state.

Negative controls, same load and the same checker, which must report loss:
(a) shim mode "nosync": fsync/fdatasync return success without syncing or
recording (writes acknowledged without durability); (b) "nodirsync":
directory fsyncs ignored (a store without them), cut after a checkpoint
renamed a new WAL into place; (c) "noparentsync": on a new state
directory, the parent's fsync after the mkdir ignored (the daemon before
this fix). And (d), for the comparison itself: one upload applied whose
logged value differs by 1e-4 in T (counters agree) must be reported as a
mismatch. Exit status 0 when every check passed and every control was
caught."""
import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "soak"))
sys.path.insert(0, os.path.join(HERE, "..", "lib"))
sys.path.insert(0, HERE)
import powercut_image as pci  # noqa: E402
from soak import Conn, csv_text, diff, dump, gen_points, status_key, tif, up_regs  # noqa: E402
from it2ntest import daemon as it2nd_proc  # noqa: E402
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

MB_UNITS = (1, 2)
LINK_UNIT = 7
UNITS = list(MB_UNITS) + [LINK_UNIT]
R = report.Report("powercut")
fail, check = R.fail, R.check
FAILS = R.fails
STARTED = []

CKPT_EVENTS = [("pre-fsync:snapshot.tmp", 0), ("post-fsync:snapshot.tmp", 0), ("post-renameat:snapshot", 0),
               ("pre-fsync:.", 0), ("post-fsync:.", 0), ("post-openat:wal.tmp", 0), ("pre-fsync:wal.tmp", 0),
               ("post-renameat:wal", 0), ("pre-fsync:.", 1), ("post-fsync:snapshot.tmp", 1)]
# Start-up recovery: named events where they exist (a torn WAL tail is kept
# in wal.cut-*, then the WAL truncated; temporary files removed), else the
# Nth state-directory event of the process.
RECOVERY_TORN = ["post-openat:wal.cut*", "pre-fsync:wal.cut*", "post-fsync:wal.cut*", "pre-fsync:.",
                 "post-ftruncate:wal"]


def now():
    return time.monotonic()


def say(msg):
    print("powercut: " + msg, flush=True)


def paper_points():
    pts = []
    fps = ["LL", "LR", "L", "D", "R", "RL", "RR"]
    with open(os.path.join(HERE, "..", "..", "examples", "paper_4x4.csv")) as f:
        next(f)
        for ln in f:
            i, j, fp, x, y = ln.strip().split(",")[:5]
            pts.append((int(i), int(j), fps.index(fp), round(float(x) * 100), round(float(y) * 100)))
    return pts


def conf_text(state, port, tmp, fsync=True, link=True):
    t = ("[daemon]\nstate_dir = %s\nsnapshot_interval = 1\nlink_backoff_max = 1\nfsync = %s\n"
         "[modbus]\ntcp_listen = 127.0.0.1:%d\n" % (state, "yes" if fsync else "no", port))
    for u in MB_UNITS:
        t += "[model:%d]\nunit_id = %d\npreload = paper\n" % (u, u)
    t += "[model:%d]\nunit_id = %d\nn = 2\nm = 2\n" % (LINK_UNIT, LINK_UNIT)
    if link:
        t += "[link:l%d]\ntype = serial\ndevice = %s\nbaud = 115200\n" % (LINK_UNIT, os.path.join(tmp, "link"))
    return t


class Daemon(it2nd_proc.Daemon):
    """start() says whether it got ready or died in start-up; stop() and
    kill9() are tests/lib's."""

    def start(self, extra_env=None, timeout=10.0):
        """'ready', or 'died' (before it was ready: a cut in start-up)."""
        pos = os.path.getsize(self.log) if os.path.exists(self.log) else 0
        env = dict(os.environ)
        env.update(extra_env or {})
        with open(self.log, "a") as logf:
            self.proc = subprocess.Popen([self.binary, "-c", self.conf, "-f", "-v"], stdout=logf,
                                         stderr=subprocess.STDOUT, env=env)
        STARTED.append(self.proc)
        deadline = now() + timeout
        while now() < deadline:
            with open(self.log, errors="replace") as f:
                f.seek(pos)
                text = f.read()
            if " ready (" in text:
                return "ready"
            if self.proc.poll() is not None:
                self.start_log = text
                return "died"
            time.sleep(0.01)
        raise RuntimeError("it2nd not ready after %.0f s" % timeout)

    def kill(self):
        return self.kill9()

    def tail(self, n=1500):
        with open(self.log, errors="replace") as f:
            return f.read()[-n:]


class Gate:
    """Load runs while `run` is set; each thread parks (idle set) when the
    harness clears it, and waits there for the next cycle."""

    def __init__(self):
        self.run = threading.Event()
        self.stop = threading.Event()


class MWriter(threading.Thread):
    """FC 23 uploads of data points of the paper model, one at a time."""

    def __init__(self, port, unit, seed, gate):
        super().__init__(daemon=True)
        self.port, self.unit, self.gate = port, unit, gate
        self.rnd = random.Random(seed)
        self.c = Conn(port, timeout=5)
        self.pts = paper_points()
        self.ops = []          # since the last check: [regs, acked]
        self.idle = threading.Event()
        self.errors = []
        self.acked_total = 0

    def run(self):
        while not self.gate.stop.is_set():
            if not self.gate.run.is_set():
                self.c.close()
                self.idle.set()
                self.gate.run.wait(0.1)
                continue
            self.idle.clear()
            if not self.gate.run.is_set():
                continue
            p = self.rnd.choice(self.pts)
            regs = up_regs(p[0], p[1], p[2], p[3], p[4], tif(self.rnd))
            op = [tuple(regs), False]
            self.ops.append(op)
            try:
                r = self.c.rw(self.unit, 40, regs, 0, 27)
            except (OSError, ValueError):
                # The cut: this operation stays in doubt; send nothing more
                # until the harness has resolved it.
                self.c.close()
                while self.gate.run.is_set():
                    time.sleep(0.01)
                continue
            if r[0] == "exc":
                self.ops.pop()      # an exception changed nothing
                self.errors.append("exception %d" % r[1])
                time.sleep(0.02)
                continue
            op[1] = True
            self.acked_total += 1
            time.sleep(0.003)   # leave the 2-core machine some air
        self.idle.set()


class LinkW(threading.Thread):
    """Instrument sessions on the pty link, one after another."""

    def __init__(self, args, tmp, port, seed, gate):
        super().__init__(daemon=True)
        self.args, self.tmp, self.port, self.gate = args, tmp, port, gate
        self.rnd = random.Random(seed)
        self.c = Conn(port, timeout=5)
        self.idle = threading.Event()
        self.proc = None
        self.done_sessions = []     # resolved while running: (session, after key)
        self.open_session = None    # ended by a cut (or unresolved): resolved by the harness
        self.stats = {"sessions": 0, "complete": 0, "cut": 0, "failed_outside_cuts": 0}
        self.failures = []

    def settled(self):
        last = None
        for _ in range(40):
            st = self.c.read(LINK_UNIT, 0, 27)
            key = status_key(st)
            if key == last:
                return key
            last = key
            time.sleep(0.1)
        raise OSError("status never settled")

    def run(self):
        while not self.gate.stop.is_set():
            if not self.gate.run.is_set() or self.open_session is not None:
                self.c.close()
                self.idle.set()
                self.gate.run.wait(0.1)
                if self.open_session is not None:
                    time.sleep(0.05)
                continue
            self.idle.clear()
            n, m = self.rnd.randint(1, 2), self.rnd.randint(1, 2)
            pts = gen_points(n, m, 0, self.rnd)
            vals = [tif(self.rnd) for _ in pts]
            csv = os.path.join(self.tmp, "inst.csv")
            with open(csv, "w") as f:
                f.write(csv_text(pts, self.rnd, vals))
            acklog = os.path.join(self.tmp, "inst.acks")
            open(acklog, "w").close()
            noise = ["--garbage", "2", "--drop", "2", "--dup", "2"] if self.rnd.random() < 0.5 else []
            cmd = [self.args.instrument, "--link", os.path.join(self.tmp, "link"), "--csv", csv, "--model",
                   str(LINK_UNIT), "--batch", str(self.rnd.randint(1, 8)), "--ack-log", acklog, "--timeout", "20",
                   "--seed", str(self.rnd.randint(1, 1 << 30))] + noise
            self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            STARTED.append(self.proc)
            out, err = self.proc.communicate()
            self.stats["sessions"] += 1
            try:
                with open(acklog) as f:
                    lines = f.read().split()
                acked = int(lines[-1]) if lines else 0
            except (OSError, ValueError):
                acked = 0
            done = self.proc.returncode == 0 and "streamed" in out
            sess = {"pts": pts, "vals": vals, "n": n, "m": m, "acked": acked, "done": done,
                    "rc": self.proc.returncode, "err": err.strip()[-300:]}
            if done:
                self.stats["complete"] += 1
            if not done and self.gate.run.is_set():
                time.sleep(0.5)     # a self-kill of the daemon: the harness sees it and clears run
            if not self.gate.run.is_set():
                self.stats["cut"] += 1
                self.open_session = sess
                continue
            if not done:
                self.stats["failed_outside_cuts"] += 1
                self.failures.append(sess["err"])
            try:
                after = self.settled()
            except (OSError, ValueError):
                self.c.close()
                self.open_session = sess
                continue
            self.done_sessions.append((sess, after))
            time.sleep(0.05)
        self.idle.set()


def link_effect(before, after, s):
    """(lost, fabricated reason or None, operations to replay)."""
    E = len(s["pts"])
    n, m = s["n"], s["m"]
    dg, dp = after[0] - before[0], after[1] - before[1]
    shape = (dg, dp) == (0, 0) or (dg == 1 and 0 <= dp < E) or (dg in (2, 3) and dp == E)
    if dg >= 1:
        shape = shape and after[2:5] == (n, m, 0) and after[5] == dp
    if not shape:
        return 0, "no prefix of the session gives %r from %r (%d entries)" % (after, before, E), []
    lost = max(0, s["acked"] - dp)
    if s["done"] and (dg, dp) != (3, E):
        lost = max(lost, 1)
    ops = []
    if dg:
        ops.append(("cmd", 2) if before[2:5] == (n, m, 0) else ("cfg", n, m, 0))
        for (i, j, fp, x, y), t in zip(s["pts"][:dp], s["vals"][:dp]):
            ops.append(("up", tuple(up_regs(i, j, fp, x, y, t))))
        if dg == 3:
            ops.append(("cmd", 1))
    return lost, None, ops


def replay_into(c, unit, ops):
    for op in ops:
        if op[0] == "cfg":
            r = c.rw(unit, 32, list(op[1:]), 0, 27)
        elif op[0] == "cmd":
            r = c.rw(unit, 35, [op[1]], 0, 27)
        else:
            r = c.rw(unit, 40, list(op[1]), 0, 27)
        if r[0] == "exc":
            return "replayed %s refused with exception %d" % (op[0], r[1])
    return None


class Harness:
    def __init__(self, args, tmp, rnd):
        self.args, self.tmp, self.rnd = args, tmp, rnd
        self.state = os.path.join(tmp, "state")
        self.shadow = os.path.join(tmp, "shadow")
        self.arm = os.path.join(tmp, "arm")
        os.mkdir(self.shadow)
        self.port, self.ref_port = free_port(), free_port()
        conf = os.path.join(tmp, "it2nd.conf")
        with open(conf, "w") as f:
            f.write(conf_text(self.state, self.port, tmp))
        self.d = Daemon(args.it2nd, conf, os.path.join(tmp, "it2nd.log"))
        self.ref_state = os.path.join(tmp, "ref-state")
        rconf = os.path.join(tmp, "ref.conf")
        with open(rconf, "w") as f:
            f.write(conf_text(self.ref_state, self.ref_port, tmp, fsync=False, link=False))
        self.ref = Daemon(args.it2nd, rconf, os.path.join(tmp, "ref.log"))
        self.gate = Gate()
        self.base = {}              # unit -> status key at the last check
        self.stats = {"cuts": 0, "cuts_random": 0, "cuts_in_checkpoint": 0, "cuts_in_commit": 0,
                      "cuts_in_recovery": 0,
                      "cut_events": {}, "torn": 0, "torn_bytes": 0, "ns_prefix_cuts": 0, "ns_ops_undone": 0,
                      "dir_absent": 0, "checks": 0, "modbus_acked": 0, "modbus_in_doubt_applied": 0,
                      "modbus_in_doubt_not_applied": 0, "link_entries_acked": 0, "link_entries_applied": 0,
                      "lost": 0, "fabricated": 0, "compare_mismatches": 0}

    def env(self, mode="", kill=None, skip=0):
        return pci.env(self.args.shim, self.state, self.shadow, mode, kill, skip, self.arm)

    def pc_start(self, mode="", kill=None, skip=0, armed=False):
        """Start under the shim; a kill event counts only while armed."""
        self.set_arm(armed)
        r = self.d.start(self.env(mode, kill, skip))
        return r

    def set_arm(self, on):
        if on:
            open(self.arm, "w").close()
        elif os.path.exists(self.arm):
            os.unlink(self.arm)

    def cut_and_rollback(self, prefix, tear, how):
        self.d.kill()
        ev = pci.killed_at(self.shadow)
        if ev:
            ev = re.sub(r"wal\.cut-\S+", "wal.cut-*", ev)
        desc = pci.rollback(self.state, self.shadow, self.rnd, prefix=prefix, tear=tear)
        self.stats["cuts"] += 1
        self.stats["cut_events"][ev or how] = self.stats["cut_events"].get(ev or how, 0) + 1
        if desc["torn"]:
            self.stats["torn"] += 1
            self.stats["torn_bytes"] += sum(desc["torn"].values())
        if prefix:
            self.stats["ns_prefix_cuts"] += 1
        self.stats["ns_ops_undone"] += desc["ops_pending"] - desc["ops_kept"]
        if not desc["dir"]:
            self.stats["dir_absent"] += 1
        return ev, desc

    def start_with_recovery_cuts(self, last_desc, allow, kill=None, skip=0):
        """Start; sometimes cut inside start-up recovery first (up to twice).
        The incarnation that serves carries kill/skip (armed later)."""
        for _ in range(2):
            torn = last_desc and last_desc.get("torn")
            # after a tear, usually: the start keeps the tail aside and cuts it
            if not allow or self.rnd.random() < (0.2 if torn else 0.6):
                break
            if torn and self.rnd.random() < 0.8:
                rk = self.rnd.choice(RECOVERY_TORN)
            else:
                rk = "#%d" % self.rnd.randint(1, 6)
            r = self.pc_start(kill=rk, armed=True)
            if r == "ready":
                # the event did not come in start-up: not a recovery cut
                # the event did not come in start-up: a cut at its end
                self.set_arm(False)
                self.cut_and_rollback(False, False, "end of start-up")
                break
            if pci.killed_at(self.shadow) is None:
                raise RuntimeError("it2nd exited in start-up by itself: %s" % self.d.tail())
            self.stats["cuts_in_recovery"] += 1
            ev, last_desc = self.cut_and_rollback(self.rnd.random() < 0.5, self.rnd.random() < 0.5, "recovery")
        r = self.pc_start(kill=kill, skip=skip, armed=False)
        if r != "ready":
            raise RuntimeError("it2nd did not start on the rolled-back state: %s" % self.d.tail())

    def wait_idle(self, threads, timeout=30):
        deadline = now() + timeout
        for t in threads:
            while not t.idle.is_set() and now() < deadline:
                # a session started as the load stopped: it talks to no one
                p = getattr(t, "proc", None)
                if p is not None and p.poll() is None:
                    p.terminate()
                time.sleep(0.01)
            if not t.idle.is_set():
                raise RuntimeError("load thread did not park")

    def check(self, writers, link, label, control=False):
        """Resolve every writer against the restarted daemon, replay into the
        reference, compare. Returns (lost, fabricated, mismatches)."""
        c, rc = Conn(self.port), Conn(self.ref_port)
        lost = fab = mism = 0
        notes = []
        for w in writers:
            key = status_key(c.read(w.unit, 0, 27))
            b = self.base[w.unit]
            k = key[1] - b[1]
            acked = sum(1 for _, a in w.ops if a)
            if any(not a for _, a in w.ops[:-1]):
                notes.append("unit %d: an unacknowledged operation before the last" % w.unit)
                fab += 1
            if k < acked:
                lost += acked - k
                notes.append("unit %d: %d operation(s) acknowledged, %d applied: %d LOST" % (w.unit, acked, k,
                                                                                              acked - k))
            if k > len(w.ops) or k < 0:
                fab += 1
                notes.append("unit %d: %d applied but %d sent: FABRICATED" % (w.unit, k, len(w.ops)))
            if len(w.ops) > acked and not control:
                self.stats["modbus_in_doubt_applied" if k > acked else "modbus_in_doubt_not_applied"] += 1
            self.stats["modbus_acked"] += acked
            err = replay_into(rc, w.unit, [("up", regs) for regs, _ in w.ops[:max(0, min(k, len(w.ops)))]])
            if err:
                fab += 1
                notes.append("unit %d: %s" % (w.unit, err))
            w.ops = []
            self.base[w.unit] = key
        # The link: sessions resolved while running, then the one the cut ended.
        sessions = list(link.done_sessions)
        link.done_sessions = []
        before = self.base[LINK_UNIT]
        if link.open_session is not None:
            sessions.append((link.open_session, status_key(c.read(LINK_UNIT, 0, 27))))
            link.open_session = None
        for s, after in sessions:
            lo, why, ops = link_effect(before, after, s)
            if why:
                fab += 1
                notes.append("unit %d: %s" % (LINK_UNIT, why))
            if lo:
                lost += lo
                notes.append("unit %d: session with %d entries ACKed%s left %r from %r: LOST" % (
                    LINK_UNIT, s["acked"], " (complete)" if s["done"] else "", after, before))
            if not control:
                self.stats["link_entries_acked"] += s["acked"]
                self.stats["link_entries_applied"] += max(0, after[1] - before[1])
            err = replay_into(rc, LINK_UNIT, ops)
            if err:
                fab += 1
                notes.append("unit %d: %s" % (LINK_UNIT, err))
            before = after
        self.base[LINK_UNIT] = before
        c.close()
        rc.close()
        # Register for register: the restarted daemon and the reference.
        d = diff(dump(self.port, "cut", UNITS), dump(self.ref_port, "reference", UNITS), UNITS)
        if d:
            mism += len(d)
            notes.extend(d[:5])
        self.stats["checks"] += 1
        if not control:
            self.stats["lost"] += lost
            self.stats["fabricated"] += fab
            self.stats["compare_mismatches"] += mism
            check(not (lost or fab or mism), "%s: every acknowledged operation there, nothing fabricated, the "
                  "registers equal the reference's" % label, "; ".join(notes))
        return lost, fab, mism, notes

    def rebaseline(self, writers):
        """After a control: the reference restarted on a copy of the state."""
        self.d.stop()
        self.ref.stop()
        shutil.rmtree(self.ref_state, ignore_errors=True)
        if os.path.isdir(self.state):
            shutil.copytree(self.state, self.ref_state)
            lock = os.path.join(self.ref_state, "lock")
            if os.path.exists(lock):
                os.unlink(lock)
        if self.ref.start() != "ready":
            raise RuntimeError("reference did not start: %s" % self.ref.tail())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--instrument", required=True)
    ap.add_argument("--shim", required=True)
    ap.add_argument("--cycles", type=int, default=32)
    ap.add_argument("--seed", type=int)
    ap.add_argument("--out")
    ap.add_argument("--keep", action="store_true")
    args = ap.parse_args()
    seed = args.seed if args.seed is not None else int(time.time()) & 0xFFFFFF
    rnd = random.Random(seed)
    tmp = tempfile.mkdtemp(prefix="it2nd-powercut.")
    t0 = now()
    say("seed %d, %d cycles, logs in %s" % (seed, args.cycles, tmp))
    h = Harness(args, tmp, rnd)
    if h.ref.start() != "ready":
        raise RuntimeError("reference did not start")
    writers = [MWriter(h.port, u, rnd.randrange(1 << 30), h.gate) for u in MB_UNITS]
    link = LinkW(args, tmp, h.port, rnd.randrange(1 << 30), h.gate)
    threads = writers + [link]

    # ---- cycle 1: a state directory that does not exist yet --------------
    if h.pc_start() != "ready":
        raise RuntimeError("it2nd did not start: %s" % h.d.tail())
    c = Conn(h.port)
    for u in UNITS:
        h.base[u] = status_key(c.read(u, 0, 27))
    c.close()
    for t in threads:
        t.start()
    last_desc = None
    for cyc in range(1, args.cycles + 1):
        kind = "random" if cyc == 1 else rnd.choice(["random", "random", "checkpoint", "checkpoint", "commit"])
        ev_k, skip = rnd.choice(CKPT_EVENTS) if kind == "checkpoint" else (None, 0)
        if kind == "commit":
            # between a WAL write and its fdatasync: an unsynced tail to tear
            ev_k, skip = "pre-fdatasync:wal", rnd.randint(5, 150)
        if cyc > 1:
            h.start_with_recovery_cuts(last_desc, allow=True, kill=ev_k, skip=skip)
            h.check(writers, link, "cycle %d" % cyc)
        prefix = cyc > 1 and rnd.random() < 0.5
        tear = cyc > 1 and rnd.random() < 0.6
        h.set_arm(True)
        h.gate.run.set()
        t_end = now() + (rnd.uniform(0.3, 1.5) if kind == "random" else 2.5)
        if cyc == 1:
            t_end = now() + 1.0
        while now() < t_end and h.d.proc.poll() is None:
            time.sleep(0.01)
        h.gate.run.clear()
        h.set_arm(False)
        if link.proc and link.proc.poll() is None:
            link.proc.terminate()
        ev, desc = h.cut_and_rollback(prefix, tear, "random")
        if ev and ev.startswith("pre-fdatasync:wal"):
            h.stats["cuts_in_commit"] += 1
        elif ev:
            h.stats["cuts_in_checkpoint"] += 1
        else:
            h.stats["cuts_random"] += 1
        h.wait_idle(threads)
        last_desc = desc
        acked_now = sum(sum(1 for _, a in w.ops if a) for w in writers)
        say("cycle %d: cut %s (%s%s%s), %d Modbus acks pending check, image %s" % (
            cyc, ev or "at a random moment", "namespace prefix %d/%d" % (desc["ops_kept"], desc["ops_pending"])
            if prefix else "strict namespace", ", torn %r" % desc["torn"] if desc["torn"] else "",
            "" if desc["dir"] else ", NO state directory", acked_now, desc["files"]))
        if cyc == 1:
            check(desc["dir"], "cycle 1: the state directory's creation made durable",
                  "never made durable (its parent not fsynced)")
    h.start_with_recovery_cuts(last_desc, allow=False)
    h.check(writers, link, "final")
    say("%d cycles: %d cuts (%d random, %d inside checkpoints, %d between a WAL write and its fdatasync, %d inside "
        "start-up recovery), %d torn, %d with a namespace prefix, %d namespace operations undone; %d Modbus writes "
        "acknowledged, link entries ACKed %d (applied %d); lost %d, fabricated %d, compare mismatches %d" % (
            args.cycles, h.stats["cuts"], h.stats["cuts_random"], h.stats["cuts_in_checkpoint"],
            h.stats["cuts_in_commit"],
            h.stats["cuts_in_recovery"], h.stats["torn"], h.stats["ns_prefix_cuts"], h.stats["ns_ops_undone"],
            h.stats["modbus_acked"], h.stats["link_entries_acked"], h.stats["link_entries_applied"],
            h.stats["lost"], h.stats["fabricated"], h.stats["compare_mismatches"]))
    say("cut events: %s" % json.dumps(h.stats["cut_events"], sort_keys=True))
    main_stats = dict(h.stats)

    # ---- negative controls: the same checker must report loss -------------
    controls = {}

    def control(name, mode, fresh=False):
        h.rebaseline(writers)
        if fresh:
            h.ref.stop()
            shutil.rmtree(h.ref_state, ignore_errors=True)
            shutil.rmtree(h.state, ignore_errors=True)
            if h.ref.start() != "ready":
                raise RuntimeError("reference did not start")
        if h.pc_start(mode=mode) != "ready":
            raise RuntimeError("it2nd (%s) did not start: %s" % (mode, h.d.tail()))
        c = Conn(h.port)
        for u in UNITS:
            h.base[u] = status_key(c.read(u, 0, 27))
        c.close()
        h.gate.run.set()
        t_start = now()
        while now() < t_start + 6:
            time.sleep(0.05)
            acks = sum(sum(1 for _, a in w.ops if a) for w in writers)
            if mode == "nodirsync":
                # a checkpoint has renamed a new WAL into place, and writes since
                evs = pci.events(h.shadow)
                if "post-renameat:wal" in evs and len(evs) - evs.index("post-renameat:wal") > 20:
                    break
            elif acks >= 10 and now() > t_start + 0.5:
                break
        h.gate.run.clear()
        if link.proc and link.proc.poll() is None:
            link.proc.terminate()
        ev, desc = h.cut_and_rollback(False, False, "control")
        h.wait_idle(threads)
        acked = sum(sum(1 for _, a in w.ops if a) for w in writers)
        r = h.pc_start()
        if r != "ready":
            controls[name] = {"mode": mode, "caught": True, "how": "the daemon refused to start",
                              "log": h.d.tail(300)}
            R.ok("control %s: caught (the daemon refused the rolled-back state)" % name)
            h.d.kill()
            return
        lost, fab, mism, notes = h.check(writers, link, "control " + name, control=True)
        caught = lost > 0
        controls[name] = {"mode": mode, "acked": acked, "lost": lost, "fabricated": fab, "mismatches": mism,
                          "caught": caught, "notes": notes[:4], "image": desc["files"], "dir": desc["dir"]}
        check(caught, "control %s (%s): caught by the checker: %s" % (name, mode, "; ".join(notes[:3])),
              "the checker did not report the loss (%d acknowledged, notes %r)" % (acked, notes))

    # (d) the comparison itself can fail: an upload the daemon applied whose
    # logged value differs by 1e-4 in T (the counters agree, only the data
    # can tell).
    w = writers[0]
    p = paper_points()[rnd.randrange(112)]
    t = tif(rnd)
    c = Conn(h.port)
    r = c.rw(w.unit, 40, up_regs(p[0], p[1], p[2], p[3], p[4], t), 0, 27)
    c.close()
    t2 = [t[0] + 1 if t[0] < 10000 else t[0] - 1] + t[1:]
    w.ops = [[tuple(up_regs(p[0], p[1], p[2], p[3], p[4], t2)), r[0] != "exc"]]
    lost, fab, mism, notes = h.check(writers, link, "control d", control=True)
    controls["d-value-changed"] = {"lost": lost, "fabricated": fab, "mismatches": mism, "caught": mism > 0,
                                   "notes": notes[:3]}
    check(mism > 0 and not lost, "control d (one applied value differs from the logged one by 1e-4): caught by "
          "the comparison: %s" % (notes[:1],), "the comparison did not see a changed value (lost %d, mismatches %d)"
          % (lost, mism))
    control("a-ack-without-fsync", "nosync")
    control("b-no-directory-fsync", "nodirsync")
    control("c-mkdir-not-durable", "noparentsync", fresh=True)
    h.gate.stop.set()
    h.gate.run.clear()
    for t in threads:
        t.join(30)
    h.d.stop()
    h.ref.stop()
    if link.failures:
        say("link sessions failed outside cuts (not durability failures; checked like the others): %d, e.g. %s"
            % (len(link.failures), link.failures[0]))
    for w in writers:
        check(not w.errors, "unit %d: no write refused" % w.unit, "%d refused: %s" % (len(w.errors), w.errors[:3]))
    check(main_stats["cuts"] >= 30, "%d cuts (at least 30)" % main_stats["cuts"])
    check(main_stats["cuts_in_checkpoint"] and main_stats["cuts_in_recovery"],
          "cuts inside a checkpoint (%d) and inside recovery (%d)" % (main_stats["cuts_in_checkpoint"],
                                                                     main_stats["cuts_in_recovery"]))
    check(main_stats["modbus_acked"] and main_stats["link_entries_acked"],
          "load: %d Modbus writes, %d link entries acknowledged" % (main_stats["modbus_acked"],
                                                                  main_stats["link_entries_acked"]))
    result = {"seed": seed, "seconds": round(now() - t0, 1), "cycles": args.cycles, "stats": main_stats,
              "link": link.stats, "controls": controls, "failures": FAILS}
    if args.out:
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        with open(args.out, "w") as f:
            json.dump(result, f, indent=2, sort_keys=True)
            f.write("\n")
    say("link: %s; %.1f s" % (json.dumps(link.stats, sort_keys=True), now() - t0))
    if args.keep and not FAILS:
        print("powercut: kept %s" % tmp)
    else:
        R.tidy(tmp)
    sys.exit(R.finish())


def cleanup():
    for p in list(STARTED):
        if p.poll() is None:
            p.kill()
            p.wait()


if __name__ == "__main__":
    import atexit
    atexit.register(cleanup)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    main()
