#!/usr/bin/python3
"""soak.py -- it2nd under load, signals, kill -9 and disk faults (issue 8,
"Tests": the soak). Drives the real daemon; loopback TCP (ports 26000-26999)
and ptys only. docs/daemon.md, "Soak", says what it checks and why.

  soak.py --it2nd BIN --instrument BIN --failio SO [--powercut SO]
          [--seconds 300] [--out FILE] [--seed S] [--keep] [--rss-tol-kib N]

For --seconds:
  * 6 writer clients, each owning one model (units 1..6), Modbus TCP: FC 23
    uploads of data points (write 40..51, read the status block), new
    configurations (32..34), COMMIT and CLEAR (35), and FC 23 queries
    (64..65 -> 128..235) on their own model;
  * 10 reader clients: status, sample grids, control-net slices and FC 23
    queries of random models;
  * 3 instruments (tests/sim/instrument, driven by its command line only),
    each on its own pty link and model (7..9): one session after another
    (CONFIGURE, PUT batches, COMMIT of a fresh random data set), half with
    link noise (garbage, drops, duplicates);
  * SIGHUP every 2-5 s (idle_timeout toggled, so the reload has work);
  * kill -9 at random moments during the first 60 % of the run (instruments
    stopped with it), restart on the same state directory, continue; with
    --powercut (tests/daemon/powercut.so, preloaded after failio.so so that
    a failed fsync is never recorded as durable) every kill is a power cut:
    the state directory is first rolled back to what fsync, fdatasync and
    directory fsyncs had made durable (tests/daemon/powercut_image.py; half
    the cuts keep a prefix of the unsynced creates/renames/unlinks, half
    tear the last unsynced write);
  * tests/daemon/failio.so preloaded, one call site of the durability path
    per daemon incarnation (alternately one that degrades the store and one
    that must refuse nothing), failing for 0.5-2 s at random moments; every
    third incarnation also on a slow disk (fsync/fdatasync +20 ms).

Verified:
  * zero acknowledged operations lost: every acknowledged write is logged
    per model in order (an operation cut off by kill -9 is resolved after the
    restart from the status block: applied whole or not at all); at the end
    the writers complete their data sets, the daemon is stopped (SIGTERM,
    exit 0) and restarted, and its state (status, control nets, sample
    grids, queries) compared register for register with the state before
    the stop and with a second, fresh it2nd into which the logged operations
    were replayed; two sensitivity replays (one operation dropped, one value
    changed by 1e-4) must differ;
  * zero unexpected failures: each failed request is classified; expected
    are connection errors between a kill -9 and shortly after the restart,
    exception 04 with last_error -200/-202 while a degrading fault is on
    (and until the recovery checkpoint), NACK -200/-202 to an instrument
    likewise, exception 06 from a model that is not solved, and instrument
    sessions disturbed by another it2nd on the machine holding their pty
    (PtyWatch, reported apart); anything else fails the soak;
  * flat RSS and fd counts: /proc/PID/status VmRSS and /proc/PID/fd sampled
    every second; over the last incarnation (no kills in the last 40 %),
    median of the last 10 samples minus median of the first 10 after a
    warm-up, RSS <= --rss-tol-kib (2048), fds <= FD_TOL (2).
Exit status 0 when every check passed.
"""
import argparse
import json
import os
import random
import signal
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "daemon"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from conn_test import Daemon  # noqa: E402
from it2ntest import report  # noqa: E402
from it2ntest.modbus import request  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402
import powercut_image as pci  # noqa: E402

RSS_TOL_KIB = 2048
FD_TOL = 2
WRITERS = 6                 # units 1..6
READERS = 10
LINKS = (7, 8, 9)           # model ids = unit ids of the instrument links
UNITS = list(range(1, WRITERS + 1)) + list(LINKS)
FPS = ["LL", "LR", "L", "D", "R", "RL", "RR"]
EIO, ENOSPC = 5, 28
# Compared registers of the status block: everything durable (state,
# degrees, flags, points, generation, points received, solves, the map
# options). Not compared: last_error 9..12 and requests/exceptions 17..20,
# live counters that differ by design (refusals, reads).
STATUS_CMP = list(range(0, 9)) + list(range(13, 17)) + list(range(21, 27))
QUERIES = [(0, 0), (2500, 7500), (5000, 5000), (10000, 3333)]

T0 = time.time()
LOCK = threading.Lock()
R = report.Report("soak")
fail = R.fail
FAILS = R.fails


def now():
    return time.time() - T0


def say(msg):
    print("soak: [%6.1f] %s" % (now(), msg), flush=True)


class ModbusError(Exception):
    pass


class Daemon(Daemon):  # noqa: F811 -- conn_test's, remembering what it started
    def start(self, *a, **k):
        try:
            super().start(*a, **k)
        finally:
            if self.proc:
                STARTED.append(self.proc)


def regs_of(body, count):
    if isinstance(body, tuple):
        return body
    if len(body) != 2 + 2 * count or body[1] != 2 * count:
        raise ValueError("bad reply length %d for %d registers" % (len(body), count))
    return struct.unpack(">%dH" % count, body[2:])


class Conn:
    """One Modbus TCP connection with its transaction ids."""

    def __init__(self, port, timeout=10.0):
        self.port, self.timeout = port, timeout
        self.s, self.tid = None, 0

    def open(self):
        self.close()
        s = socket.create_connection(("127.0.0.1", self.port), timeout=self.timeout)
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.s = s

    def close(self):
        if self.s:
            try:
                self.s.close()
            except OSError:
                pass
        self.s = None

    def _req(self, unit, pdu):
        if not self.s:
            self.open()
        self.tid = (self.tid + 1) & 0xFFFF
        return request(self.s, unit, pdu, self.tid)

    def read(self, unit, addr, count, fc=4):
        return regs_of(self._req(unit, struct.pack(">BHH", fc, addr, count)), count)

    def write(self, unit, addr, vals):
        if len(vals) == 1:
            r = self._req(unit, struct.pack(">BHH", 6, addr, vals[0]))
        else:
            r = self._req(unit, struct.pack(">BHHB", 16, addr, len(vals), 2 * len(vals))
                          + struct.pack(">%dH" % len(vals), *vals))
        return r if isinstance(r, tuple) else "ok"

    def rw(self, unit, waddr, vals, raddr, rcount):
        """FC 23: write vals at waddr, then read rcount at raddr."""
        pdu = struct.pack(">BHHHHB", 23, raddr, rcount, waddr, len(vals), 2 * len(vals)) \
            + struct.pack(">%dH" % len(vals), *vals)
        return regs_of(self._req(unit, pdu), rcount)


def i32(v):
    v &= 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


def status_key(st):
    """(generation, points received, n, m, flags, points present, state)."""
    return (st[7] << 16 | st[8], st[13] << 16 | st[14], st[2], st[3], st[4], st[5], st[1])


def gen_points(n, m, flags, rnd):
    """A valid data set (coordinates in hundredths, footprints nested on x
    and y as tests/daemon/gen_dataset.py): [(i, j, fp, x, y)] in the
    instrument's stream order (i, j, footprint)."""
    pts = []
    for i in range(n + 1):
        for j in range(m + 1):
            x, y = i * 1000 + rnd.randint(-300, 300), j * 1000 + rnd.randint(-300, 300)
            s = [0]
            for _ in range(3):
                s.append(s[-1] + rnd.randint(10, 100))
            offs = [-s[3], -s[2], -s[1], 0, s[1], s[2], s[3]]
            for fp in range(7):
                if flags & 2 and fp != 3:
                    continue
                pts.append((i, j, fp, x + offs[fp], y + offs[fp]))
    return pts


def tif(rnd):
    return [rnd.randint(0, 10000), rnd.randint(0, 10000), rnd.randint(1, 10000)]


def up_regs(i, j, fp, x, y, t):
    return [i, j, fp] + i32(x) + i32(y) + [0, 0] + list(t)


# ---- the timeline: kills and fault windows ---------------------------------

class Timeline:
    def __init__(self):
        self.restarts = []   # [t_kill, t_ready]
        self.faults = []     # [t_on, t_off, degrades]
        self.lock = threading.Lock()

    def in_restart(self, t):
        with self.lock:
            for a, b in self.restarts:
                if a - 0.05 <= t and (b is None or t <= b + 1.5):
                    return True
        return False

    def near(self, t):
        with self.lock:
            return [(round(a, 2), b and round(b, 2), d) for a, b, d in self.faults if abs(a - t) < 10]

    def in_degrade(self, t):
        with self.lock:
            for a, b, deg in self.faults:
                if deg and a - 0.05 <= t and (b is None or t <= b + 3.0):
                    return True
        return False


TL = Timeline()


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.c = {}
        self.unexpected = []
        self.known = []     # instrument sessions that failed: command, stderr

    def inc(self, key, k=1):
        with self.lock:
            self.c[key] = self.c.get(key, 0) + k

    def unexp(self, who, what):
        with self.lock:
            self.unexpected.append("%.1f %s: %s" % (now(), who, what))
        print("soak: unexpected failure: %s: %s" % (who, what), file=sys.stderr, flush=True)


ST = Stats()
STOP = threading.Event()


def conn_failed(who, e, t):
    if TL.in_restart(t) or TL.in_restart(now()):
        ST.inc("conn_errors_in_restart_windows")
    else:
        ST.unexp(who, "connection error outside a restart window: %r" % (e,))


def reconnect(c, who):
    while not STOP.is_set() or who.startswith("final"):
        try:
            c.open()
            return True
        except OSError:
            time.sleep(0.05)
    return False


# ---- writers: one model each, every acknowledged operation logged ----------

class ModelLog:
    """The operations a model went through, in order, as Modbus writes that
    replay them: ("cfg", n, m, flags) | ("up", regs) | ("cmd", 1|2), each with
    the status key after it (None when resolved from a restart)."""

    def __init__(self, unit):
        self.unit = unit
        self.ops = []
        self.lock = threading.Lock()

    def add(self, op, key):
        with self.lock:
            self.ops.append((op, key))


LOGS = {u: ModelLog(u) for u in UNITS}


def expected_after(op, key):
    gen, prx, n, m, flags, present, state = key
    if op[0] == "cfg":
        return (gen + 1, prx, op[1], op[2], op[3], 0, 0)
    if op[0] == "cmd":
        if op[1] == 2:
            return (gen + 1, prx, n, m, flags, 0, 0)
        return (gen + 1, prx, n, m, flags, present, 2)
    return None  # an upload: checked field by field in resolve()


def required(n, m, flags):
    return (n + 1) * (m + 1) * (1 if flags & 2 else 7)


class Writer(threading.Thread):
    def __init__(self, port, unit, seed, initial):
        super().__init__(daemon=True)
        self.port, self.unit = port, unit
        self.rnd = random.Random(seed)
        self.who = "writer %d" % unit
        self.c = Conn(port)
        self.key = None           # status key after the last known operation
        self.pts = None           # current data set's coordinates
        self.present = set()
        self.cfg = initial

    def status(self):
        return self.c.read(self.unit, 0, 27)

    def new_dataset(self):
        n, m, flags = self.cfg
        self.pts = gen_points(n, m, flags, self.rnd)

    def do(self, op, regs_w, waddr):
        """Run one write operation as FC 23 (write, read the status block).
        Returns True when acknowledged."""
        t = now()
        try:
            st = self.c.rw(self.unit, waddr, regs_w, 0, 27)
        except (OSError, ValueError) as e:
            conn_failed(self.who, e, t)
            self.resolve(op)
            return None
        if st[0] == "exc":
            code = st[1]
            le = None
            try:
                le = self.status()[9]
                le = le - 65536 if le >= 32768 else le
            except (OSError, ValueError) as e:
                conn_failed(self.who, e, now())
                self.c.close()
                reconnect(self.c, self.who)
            if code == 4 and le in (-200, -202, None) and (TL.in_degrade(t) or TL.in_degrade(now())):
                ST.inc("refused_04_while_degraded")
            else:
                ST.unexp(self.who, "%s sent at %.2f refused with exception %d, last_error %s at %.2f; fault windows "
                         "(on, off, degrades) near: %s" % (op[0], t, code, le, now(), TL.near(t)))
            ST.inc("writes_refused")
            time.sleep(0.02)  # refused at once: do not spin
            return False
        key = status_key(st)
        self.check_effect(op, self.key, key)
        self.key = key
        LOGS[self.unit].add(op, key)
        ST.inc("writes_acked")
        ST.inc("acked_%s" % (op[0] if op[0] != "cmd" else ("commit" if op[1] == 1 else "clear")))
        return True

    def check_effect(self, op, before, after):
        """The status after an acknowledged operation must be its effect."""
        if before is None:
            return
        exp = expected_after(op, before)
        if exp is None:
            gen, prx, n, m, flags, present, state = before
            # an update of a solved model, or the point that completes it,
            # solves: generation + 1; any other point leaves it
            ok = after[1] == prx + 1 and after[2:5] == (n, m, flags) and after[5] in (present, present + 1)
            ok = ok and after[0] == (gen + 1 if after[6] == 2 else gen) and (state != 2 or after[6] == 2)
            ok = ok and (after[6] != 2 or after[5] == required(n, m, flags))
        else:
            ok = after[:6] == exp[:6] and (op[0] != "cmd" or op[1] != 1 or after[6] == 2)
        if not ok:
            fail("%s: %s acknowledged but the status after it is %r (before %r)" % (self.who, op[0], after, before))

    def resolve(self, op):
        """The connection broke during op: after the restart, the status
        block tells whether it was applied (a whole operation, or nothing)."""
        ST.inc("writes_in_doubt")
        self.c.close()
        time.sleep(0.2)
        while True:
            if not reconnect(self.c, "final " + self.who):
                return
            try:
                st = self.status()
                break
            except (OSError, ValueError):
                time.sleep(0.1)
        key = status_key(st)
        b = self.key
        if key == b:
            ST.inc("in_doubt_not_applied")
            return
        exp = expected_after(op, b)
        if exp is None:
            gen, prx, n, m, flags, present, state = b
            applied = key[1] == prx + 1 and key[2:5] == (n, m, flags) and key[0] in (gen, gen + 1)
        else:
            applied = key[:6] == exp[:6]
        if applied:
            ST.inc("in_doubt_applied")
            self.key = key
            LOGS[self.unit].add(op, key)
        else:
            fail("%s: after the restart the model is neither before nor after the %s cut off: %r (before %r)"
                 % (self.who, op[0], key, b))
            self.key = key

    def sync_local(self):
        """Local view (present points, config) from self.key after a change."""
        gen, prx, n, m, flags, present, state = self.key
        if (n, m, flags) != self.cfg or present == 0:
            if (n, m, flags) != self.cfg:
                self.cfg = (n, m, flags)
                self.new_dataset()
            if present == 0:
                self.present = set()

    def run(self):
        reconnect(self.c, self.who)
        while self.key is None and not STOP.is_set():
            try:
                self.key = status_key(self.status())
            except (OSError, ValueError) as e:
                conn_failed(self.who, e, now())
                self.c.close()
                reconnect(self.c, self.who)
        if self.key is None:
            return
        self.cfg = self.key[2:5]
        self.new_dataset()
        # Start the data set over (the preload's coordinates are not ours).
        while not STOP.is_set() and not self.do(("cmd", 2), [2], 35):
            time.sleep(0.2)
        self.present = set()
        while not STOP.is_set():
            self.sync_local()
            n, m, flags = self.cfg
            complete = self.key[5] == required(n, m, flags)
            solved = self.key[6] == 2
            r = self.rnd.random()
            if complete and solved and r < 0.10:
                op = ("cmd", 1)
                self.do(op, [1], 35)
            elif complete and r < 0.12:
                op = ("cmd", 2)
                if self.do(op, [2], 35):
                    self.present = set()
            elif complete and r < 0.15:
                while True:
                    cfg = (self.rnd.randint(1, 3), self.rnd.randint(1, 3), self.rnd.choice((0, 0, 2)))
                    if cfg != self.cfg:
                        break
                op = ("cfg",) + cfg
                if self.do(op, list(cfg), 32):
                    self.cfg = cfg
                    self.new_dataset()
                    self.present = set()
            elif complete and solved and r < 0.30:
                u, w = self.rnd.randint(0, 10000), self.rnd.randint(0, 10000)
                t = now()
                try:
                    res = self.c.rw(self.unit, 64, [u, w], 128, 108)
                    if res[0] == "exc":
                        ST.unexp(self.who, "query on its solved model: exception %d" % res[1])
                    ST.inc("writer_queries")
                except (OSError, ValueError) as e:
                    conn_failed(self.who, e, t)
                    self.c.close()
                    reconnect(self.c, self.who)
            else:
                if not complete and self.rnd.random() < 0.85:
                    cand = [p for p in self.pts if p[:3] not in self.present] or self.pts
                else:
                    cand = self.pts
                p = self.rnd.choice(cand)
                regs = up_regs(p[0], p[1], p[2], p[3], p[4], tif(self.rnd))
                op = ("up", tuple(regs))
                if self.do(op, regs, 40):
                    self.present.add(p[:3])
                elif self.key[5] == 0:
                    self.present = set()
            # whatever happened, the local view follows the status
            if self.key[5] == 0:
                self.present = set()
        # The end: complete the data set (the model solves), so that the
        # final comparison covers nets, grids and queries of this model too.
        t_end = time.time() + 15
        while time.time() < t_end and self.key[5] != required(*self.cfg):
            self.sync_local()
            cand = [p for p in self.pts if p[:3] not in self.present] or self.pts
            p = self.rnd.choice(cand)
            regs = up_regs(p[0], p[1], p[2], p[3], p[4], tif(self.rnd))
            if self.do(("up", tuple(regs)), regs, 40):
                self.present.add(p[:3])


# ---- readers -------------------------------------------------------------------

class Reader(threading.Thread):
    def __init__(self, port, k, seed):
        super().__init__(daemon=True)
        self.c = Conn(port)
        self.rnd = random.Random(seed)
        self.who = "reader %d" % k
        self.gen_seen = {}

    def run(self):
        reconnect(self.c, self.who)
        while not STOP.is_set():
            unit = self.rnd.choice(UNITS)
            kind = self.rnd.randrange(4)
            t = now()
            try:
                st = self.c.read(unit, 0, 27)
                g = st[7] << 16 | st[8]
                if g < self.gen_seen.get(unit, 0):
                    fail("%s: unit %d generation went back from %d to %d (a read showed a change that was "
                         "undone)" % (self.who, unit, self.gen_seen[unit], g))
                self.gen_seen[unit] = g
                if kind == 0:
                    r = self.c.read(unit, 1024, st[23] * st[24] * 3)
                elif kind == 1:
                    r = self.c.read(unit, 2048 + 125 * self.rnd.randrange(43), 125, fc=3)
                elif kind == 2:
                    r = self.c.rw(unit, 64, [self.rnd.randint(0, 10000), self.rnd.randint(0, 10000)], 128, 108)
                else:
                    r = self.c.read(unit, 8192 + 120 * self.rnd.randrange(st[23] * st[24] * 6 // 120),
                                    min(120, st[23] * st[24] * 6))
                ST.inc("reads")
                if r[0] == "exc":
                    st2 = self.c.read(unit, 0, 27)
                    if r[1] == 6 and (st[1] != 2 or st2[1] != 2 or st2[7:9] != st[7:9]):
                        ST.inc("reads_06_not_solved")
                    else:
                        ST.unexp(self.who, "unit %d kind %d: exception %d (state %d)" % (unit, kind, r[1], st[1]))
            except (OSError, ValueError) as e:
                conn_failed(self.who, e, t)
                self.c.close()
                reconnect(self.c, self.who)
            time.sleep(0.005)


# ---- instruments -----------------------------------------------------------------

def csv_text(pts, rnd, vals):
    out = ["i,j,footprint,x,y,T,I,F"]

    def f2(v):
        return "%s%d.%02d" % ("-" if v < 0 else "", abs(v) // 100, abs(v) % 100)

    def f4(v):
        return "%d.%04d" % (v // 10000, v % 10000)
    for (i, j, fp, x, y), t in zip(pts, vals):
        out.append("%d,%d,%s,%s,%s,%s,%s,%s" % (i, j, FPS[fp], f2(x), f2(y), f4(t[0]), f4(t[1]), f4(t[2])))
    return "\n".join(out) + "\n"


class PtyWatch(threading.Thread):
    """Other it2nd processes on this machine that hold one of our links'
    ptys open. A daemon whose link device is a stale symlink to /dev/pts/N
    opens whatever pty the kernel numbers N next -- possibly an instrument
    of this soak, whose frames it then answers (NACK -113, unknown model).
    Seen holders are recorded per pty: such a session's failure is the
    environment's, reported apart, not the soaked daemon's."""

    def __init__(self, tmp, mine):
        super().__init__(daemon=True)
        self.tmp, self.mine = tmp, mine     # mine(): pids of this soak
        self.seen = {}                      # "/dev/pts/N" -> {(pid, cmdline)}
        self.lock = threading.Lock()

    def scan(self):
        ptys = set()
        for u in LINKS:
            try:
                ptys.add(os.readlink(os.path.join(self.tmp, "link%d" % u)))
            except OSError:
                pass
        if not ptys:
            return
        mine = self.mine()
        for pid in os.listdir("/proc"):
            if not pid.isdigit() or int(pid) in mine:
                continue
            try:
                with open("/proc/%s/comm" % pid) as f:
                    if not f.read().startswith("it2nd"):
                        continue
                fds = os.listdir("/proc/%s/fd" % pid)
            except OSError:
                continue
            for fd in fds:
                try:
                    tgt = os.readlink("/proc/%s/fd/%s" % (pid, fd))
                except OSError:
                    continue
                if tgt in ptys:
                    try:
                        with open("/proc/%s/cmdline" % pid) as f:
                            cmd = f.read().replace("\0", " ").strip()
                    except OSError:
                        cmd = "?"
                    with self.lock:
                        self.seen.setdefault(tgt, set()).add((int(pid), cmd))

    def holders(self, pty):
        with self.lock:
            return sorted(self.seen.get(pty, ()))

    def run(self):
        while not STOP.is_set():
            self.scan()
            time.sleep(0.25)


WATCH = None


class Link(threading.Thread):
    """Instrument sessions one after another on the pty link of model
    `unit`; each session resolved from the status block before the next."""

    def __init__(self, port, unit, seed, args, tmp):
        super().__init__(daemon=True)
        self.port, self.unit, self.args, self.tmp = port, unit, args, tmp
        self.rnd = random.Random(seed)
        self.c = Conn(port)
        self.who = "instrument %d" % unit
        self.proc = None
        self.killed = False
        self.sessions = 0

    def settled_status(self):
        last = None
        while True:
            try:
                st = self.c.read(self.unit, 0, 27)
                key = status_key(st)
                if key == last:
                    return key
                last = key
                time.sleep(0.15)
            except (OSError, ValueError):
                self.c.close()
                time.sleep(0.1)
                if not reconnect(self.c, "final " + self.who):
                    return None

    def run(self):
        key = self.settled_status()
        while not STOP.is_set():
            n, m = self.rnd.randint(1, 3), self.rnd.randint(1, 3)
            pts = gen_points(n, m, 0, self.rnd)
            vals = [tif(self.rnd) for _ in pts]
            csv = os.path.join(self.tmp, "inst%d.csv" % self.unit)
            with open(csv, "w") as f:
                f.write(csv_text(pts, self.rnd, vals))
            acklog = os.path.join(self.tmp, "inst%d.acks" % self.unit)
            open(acklog, "w").close()
            batch = self.rnd.randint(1, 8)
            noise = ["--garbage", "2", "--drop", "2", "--dup", "2"] if self.rnd.random() < 0.5 else []
            cmd = [self.args.instrument, "--link", os.path.join(self.tmp, "link%d" % self.unit), "--csv", csv,
                   "--model", str(self.unit), "--batch", str(batch), "--ack-log", acklog, "--timeout", "20",
                   "--seed", str(self.rnd.randint(1, 1 << 30))] + noise
            t = now()
            self.killed = False
            self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            STARTED.append(self.proc)
            pty = None
            for _ in range(40):     # the instrument's pty, for PtyWatch
                try:
                    pty = os.readlink(os.path.join(self.tmp, "link%d" % self.unit))
                    break
                except OSError:
                    time.sleep(0.01)
            out, err = self.proc.communicate()
            foreign = WATCH.holders(pty) if WATCH and pty else []
            rc = self.proc.returncode
            self.sessions += 1
            acked = 0
            try:
                with open(acklog) as f:
                    lines = f.read().split()
                    acked = int(lines[-1]) if lines else 0
            except (OSError, ValueError):
                pass
            done = rc == 0 and "streamed" in out
            if not done:
                if self.killed:
                    ST.inc("instrument_sessions_cut_by_kill")
                elif rc == 1 and ("refused: -200" in err or "refused: -202" in err) and \
                        (TL.in_degrade(t) or TL.in_degrade(now())):
                    ST.inc("instrument_sessions_nacked_while_degraded")
                elif TL.in_restart(now()):
                    ST.inc("instrument_sessions_failed_in_restart_window")
                elif foreign:
                    # Another it2nd on this machine opened this session's
                    # pty (PtyWatch): the environment's failure, not ours.
                    ST.inc("instrument_sessions_disturbed_by_a_foreign_it2nd")
                    ST.known.append({"t": round(t, 2), "cmd": cmd, "rc": rc, "stderr": err[-2000:], "pty": pty,
                                     "foreign_holders": [list(h) for h in foreign]})
                    print("soak: %s: session failed while another it2nd held its pty %s: %r (not counted as the "
                          "daemon's failure)" % (self.who, pty, foreign), file=sys.stderr, flush=True)
                else:
                    ST.unexp(self.who, "session exit %d: %s" % (rc, (err or out).strip()[-300:]))
                    ST.known.append({"t": round(t, 2), "cmd": cmd, "rc": rc, "stderr": err[-4000:], "pty": pty,
                                     "unexpected": True})
                    keep = os.path.join(self.tmp, "failed-session-%d-%d.csv" % (self.unit, self.sessions))
                    subprocess.call(["cp", csv, keep])
            else:
                ST.inc("instrument_sessions_complete")
            time.sleep(0.3)
            after = self.settled_status()
            if after is None:
                return
            self.resolve(key, after, pts, vals, acked, done, n, m)
            key = after

    def resolve(self, before, after, pts, vals, acked, done, n, m):
        E = len(pts)
        dg, dp = after[0] - before[0], after[1] - before[1]
        ok_shape = (dg, dp) == (0, 0) or (dg == 1 and 0 <= dp < E) or (dg in (2, 3) and dp == E)
        if dg >= 1:
            ok_shape = ok_shape and after[2:5] == (n, m, 0) and after[5] == dp
        if not ok_shape:
            fail("%s: session left the model in a state no prefix of it explains: before %r after %r (%d entries)"
                 % (self.who, before, after, E))
            return
        if dp < acked:
            fail("%s: %d entries ACKed but only %d applied (lost acknowledged data)" % (self.who, acked, dp))
        if done and (dg, dp) != (3, E):
            fail("%s: session complete but the model moved by %r" % (self.who, (dg, dp)))
        ST.inc("instrument_entries_acked", acked)
        ST.inc("instrument_entries_applied", dp)
        if dg == 0:
            return
        log = LOGS[self.unit]
        # A CONFIGURE of the running configuration restarts the model:
        # through the map that is a CLEAR (a configuration write with the
        # same values is no change).
        if before[2:5] == (n, m, 0):
            log.add(("cmd", 2), None)
        else:
            log.add(("cfg", n, m, 0), None)
        for (i, j, fp, x, y), t in zip(pts[:dp], vals[:dp]):
            log.add(("up", tuple(up_regs(i, j, fp, x, y, t))), None)
        if dg == 3:
            log.add(("cmd", 1), None)
        log.ops[-1] = (log.ops[-1][0], after)


# ---- final state -----------------------------------------------------------------

def dump(port, who, units=UNITS):
    """Everything compared: selected status registers, sample grid (both
    views), control nets, FC 23 query results; exception codes where the
    model is not solved."""
    c = Conn(port)
    c.open()
    out = {}
    for u in units:
        st = c.read(u, 0, 27)
        d = {"status": [st[k] for k in STATUS_CMP]}
        nodes = st[23] * st[24]
        d["grid"] = c.read(u, 1024, nodes * 3)
        d["grid_f32"] = []
        for a in range(0, nodes * 6, 120):
            r = c.read(u, 8192 + a, min(120, nodes * 6 - a))
            d["grid_f32"].extend(r if r[0] != "exc" else [r])
        net = []
        for a in range(2048, 7424, 125):
            net.extend(c.read(u, a, min(125, 7424 - a)))
        d["net"] = net
        d["query"] = []
        for qu, qw in QUERIES:
            d["query"].extend(c.rw(u, 64, [qu, qw], 128, 108))
        out[u] = d
    c.close()
    return out


def diff(a, b, units=UNITS):
    bad = []
    for u in units:
        for k in a[u]:
            if list(a[u][k]) != list(b[u][k]):
                x, y = list(a[u][k]), list(b[u][k])
                first = next((i for i in range(min(len(x), len(y))) if x[i] != y[i]), min(len(x), len(y)))
                bad.append("unit %d %s differs at %d: %r vs %r" % (u, k, first, x[first:first + 4], y[first:first + 4]))
    return bad


def replay(port, units=UNITS, logs=None, check_keys=True):
    """Replay every model's operations into the fresh daemon (one thread per
    model); each must be acknowledged, and give the status recorded."""
    errs = []
    logs = logs or {u: LOGS[u].ops for u in units}

    def one(u):
        c = Conn(port)
        c.open()
        for op, key in logs[u]:
            if op[0] == "cfg":
                r = c.rw(u, 32, list(op[1:]), 0, 27)
            elif op[0] == "cmd":
                r = c.rw(u, 35, [op[1]], 0, 27)
            else:
                r = c.rw(u, 40, list(op[1]), 0, 27)
            if r[0] == "exc":
                errs.append("unit %d: replayed %s refused with exception %d" % (u, op[0], r[1]))
                return
            if check_keys and key is not None and status_key(r) != key:
                errs.append("unit %d: replayed %s gives status %r, the soaked daemon said %r"
                            % (u, op[0], status_key(r), key))
                return
        c.close()
    ts = [threading.Thread(target=one, args=(u,)) for u in units]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    return errs


# ---- the daemon -------------------------------------------------------------------

FAULTS = [  # name, call, path suffix (state dir name substituted), skip, errno, degrades
    ("wal-write", "write", "/wal", 0, ENOSPC, True),
    ("wal-fdatasync", "fdatasync", "/wal", 0, EIO, True),
    ("wal-write-truncate", "write,ftruncate", "/wal", 0, EIO, True),
    ("snap-open", "openat", "snapshot.tmp", 0, ENOSPC, False),
    ("snap-write", "write", "/snapshot.tmp", 0, ENOSPC, False),
    ("snap-fsync", "fsync", "/snapshot.tmp", 0, EIO, False),
    ("snap-rename", "renameat", "snapshot.tmp", 0, EIO, False),
    ("walnew-open", "openat", "wal.tmp", 0, ENOSPC, False),
    ("walnew-write", "write", "/wal.tmp", 0, ENOSPC, False),
    ("walnew-fsync", "fsync", "/wal.tmp", 0, EIO, False),
    ("walnew-rename", "renameat", "wal.tmp", 0, EIO, False),
    ("snap-dirsync", "fsync", "/STATE", 0, EIO, False),
    ("walnew-dirsync", "fsync", "/STATE", 1, EIO, True),
]


def conf_text(state, port, tmp, idle, links=True, fsync=True):
    t = ("[daemon]\nstate_dir = %s\nsnapshot_interval = 3\nlink_backoff_max = 1\nmax_models = 12\nfsync = %s\n"
         "[modbus]\ntcp_listen = 127.0.0.1:%d\nidle_timeout = %d\n" % (state, "yes" if fsync else "no", port, idle))
    t += "[model:1]\nunit_id = 1\npreload = paper\n"
    for u in UNITS[1:]:
        t += "[model:%d]\nunit_id = %d\nn = 2\nm = 2\n" % (u, u)
    if links:
        for u in LINKS:
            t += "[link:l%d]\ntype = serial\ndevice = %s\nbaud = 115200\n" % (u, os.path.join(tmp, "link%d" % u))
    return t


def proc_sample(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            rss = next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))
        return rss, len(os.listdir("/proc/%d/fd" % pid))
    except (OSError, StopIteration, ValueError):
        return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--instrument", required=True)
    ap.add_argument("--failio", required=True)
    ap.add_argument("--powercut", help="powercut.so: every kill -9 becomes a power cut")
    ap.add_argument("--seconds", type=float, default=300)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--out")
    ap.add_argument("--keep", action="store_true", help="keep the temporary directory")
    ap.add_argument("--rss-tol-kib", type=int, default=RSS_TOL_KIB,
                    help="RSS growth tolerance (a sanitizer build's allocator quarantine grows by design)")
    args = ap.parse_args()
    seed = args.seed if args.seed is not None else int(time.time()) & 0xFFFFFF
    rnd = random.Random(seed)
    tmp = tempfile.mkdtemp(prefix="it2nd-soak.")
    state = os.path.join(tmp, "state")
    shadow = os.path.join(tmp, "powercut-shadow")
    os.mkdir(shadow)
    port = free_port()
    say("seed %d, %.0f s, port %d, logs in %s" % (seed, args.seconds, port, tmp))
    flag = os.path.join(tmp, "fault-flag")
    inc = [0]
    idle = [300]
    cur = {}

    def start():
        inc[0] += 1
        # Alternate: incarnations 1, 3, ... fail a call site that degrades
        # the store, 2, 4, ... one whose failure must refuse nothing.
        kinds = [f for f in FAULTS if f[5] == (inc[0] % 2 == 1)]
        f = kinds[rnd.randrange(len(kinds))]
        path = f[2].replace("STATE", os.path.basename(state))
        preload = args.failio + (":" + args.powercut if args.powercut else "")
        env = ["env", "LD_PRELOAD=" + preload, "IT2N_FAILIO_FLAG=" + flag, "IT2N_FAILIO_CALL=" + f[1],
               "IT2N_FAILIO_PATH=" + path, "IT2N_FAILIO_SKIP=%d" % f[3], "IT2N_FAILIO_ERRNO=%d" % f[4]]
        # Every third incarnation on a slow disk too: fsync/fdatasync 20 ms.
        delay = 20 if inc[0] % 3 == 0 else 0
        env.append("IT2N_FAILIO_DELAY_MS=%d" % delay)
        if args.powercut:
            env += ["%s=%s" % kv for kv in sorted(pci.env(args.powercut, state, shadow).items()) if kv[0] != "LD_PRELOAD"]
        d = Daemon(args.it2nd, tmp, "soak-%d" % inc[0])
        d.start(conf_text(state, port, tmp, idle[0]), " ready (", prefix=env)
        cur.update(d=d, fault=f, pid=d.proc.pid, samples=[], t_start=now(), delay=delay)
        return d

    start()
    say("incarnation 1 (fault site %s, fsync delay %d ms)" % (cur["fault"][0], cur["delay"]))
    threads = [Writer(port, u, rnd.randrange(1 << 30), None) for u in range(1, WRITERS + 1)]
    threads += [Reader(port, k, rnd.randrange(1 << 30)) for k in range(READERS)]
    links = [Link(port, u, rnd.randrange(1 << 30), args, tmp) for u in LINKS]
    global WATCH
    WATCH = PtyWatch(tmp, lambda: {os.getpid(), cur["pid"]} | {lk.proc.pid for lk in links if lk.proc})
    WATCH.start()
    for t in threads + links:
        t.start()

    kill_end = args.seconds * (0.5 if args.seconds < 120 else 0.6)
    t_next_hup = now() + rnd.uniform(2, 5)
    t_next_kill = now() + rnd.uniform(4, min(20, kill_end - 2))
    t_next_fault = now() + rnd.uniform(2, 6)
    fault_off_at = None
    last_sample = 0
    incarnations = []
    kills = hups = faults = 0
    powercuts = []
    crashed = 0
    while now() < args.seconds:
        t = now()
        d = cur["d"]
        if d.proc.poll() is not None:
            fail("it2nd exited by itself (status %s): %s" % (d.proc.returncode, d.logtext()[-1500:]))
            crashed += 1
            with TL.lock:
                TL.restarts.append([now(), None])
            start()
            with TL.lock:
                TL.restarts[-1][1] = now()
            continue
        if t - last_sample >= 1.0:
            s = proc_sample(cur["pid"])
            if s:
                cur["samples"].append((t - cur["t_start"], s[0], s[1]))
            last_sample = t
        if t >= t_next_hup:
            idle[0] = 301 if idle[0] == 300 else 300
            d.write(conf_text(state, port, tmp, idle[0]))
            d.hup()
            hups += 1
            t_next_hup = t + rnd.uniform(2, 5)
        if fault_off_at is None and t >= t_next_fault:
            # The window opens before the flag exists (a client may see the
            # refusal before this thread runs again) and closes after it is gone.
            with TL.lock:
                TL.faults.append([now(), None, cur["fault"][5]])
            open(flag, "w").close()
            faults += 1
            fault_off_at = t + rnd.uniform(0.5, 2.0)
        elif fault_off_at is not None and t >= fault_off_at:
            os.unlink(flag)
            with TL.lock:
                TL.faults[-1][1] = now()
            fault_off_at = None
            t_next_fault = now() + rnd.uniform(3, 10)
        if t >= t_next_kill and t < kill_end:
            with TL.lock:
                TL.restarts.append([now(), None])
            d.proc.send_signal(signal.SIGKILL)
            d.proc.wait()
            cut = ""
            if args.powercut:
                desc = pci.rollback(state, shadow, rnd, prefix=rnd.random() < 0.5, tear=rnd.random() < 0.5)
                powercuts.append(desc)
                cut = " (power cut: %s%s%s)" % ("namespace operations kept %d of %d unsynced"
                                                % (desc["ops_kept"], desc["ops_pending"]),
                                                ", torn %r" % desc["torn"] if desc["torn"] else "",
                                                "" if desc["dir"] else ", NO state directory")
            for lk in links:
                if lk.proc and lk.proc.poll() is None:
                    lk.killed = True
                    lk.proc.terminate()
            kills += 1
            if fault_off_at is not None:
                os.unlink(flag)
                with TL.lock:
                    TL.faults[-1][1] = now()
                fault_off_at = None
                t_next_fault = now() + rnd.uniform(3, 10)
            incarnations.append(dict(fault=cur["fault"][0], samples=cur["samples"], delay=cur["delay"]))
            time.sleep(rnd.uniform(0, 0.3))
            start()
            with TL.lock:
                TL.restarts[-1][1] = now()
            say("kill -9 #%d%s; incarnation %d up (fault site %s, fsync delay %d ms)"
                % (kills, cut, inc[0], cur["fault"][0], cur["delay"]))
            t_next_kill = now() + rnd.uniform(6, 20)
        time.sleep(0.05)

    # ---- stop the load ----
    if fault_off_at is not None:
        os.unlink(flag)
        with TL.lock:
            TL.faults[-1][1] = now()
    say("load stops")
    STOP.set()
    for t in threads:
        t.join(30)
    for lk in links:
        lk.join(40)
        if lk.is_alive():
            fail("%s did not finish its session" % lk.who)
    incarnations.append(dict(fault=cur["fault"][0], samples=cur["samples"], delay=cur["delay"], last=True))
    d = cur["d"]
    log_text = "".join(Daemon(args.it2nd, tmp, "soak-%d" % k).logtext() for k in range(1, inc[0] + 1))

    # ---- the final state, kill -9, restart, replay ----
    before = dump(port, "soaked")
    # A clean stop of the long-lived last incarnation (exit status 0: its
    # final snapshot written; on a sanitizer build no leak reported), a
    # restart, and the same state (kill -9 and restarts were mid-run).
    rc = d.stop()
    R.check(rc == 0, "soaked daemon: SIGTERM, exit status 0 (final snapshot written; no leak on a sanitizer build)",
            "%s: %s" % (rc, d.logtext()[-1500:]))
    d2 = Daemon(args.it2nd, tmp, "after-stop")
    d2.start(conf_text(state, port, tmp, idle[0]), " ready (")
    after = dump(port, "restarted")
    rc = d2.stop()
    R.check(rc == 0, "restarted daemon: SIGTERM, exit status 0", rc)
    lost_kill = diff(before, after)
    ref_port = free_port()
    ref = Daemon(args.it2nd, tmp, "reference")
    ref.start(conf_text(os.path.join(tmp, "ref-state"), ref_port, tmp, idle[0], links=False, fsync=False), " ready (")
    rerr = replay(ref_port)
    refd = dump(ref_port, "reference")
    ref.stop()
    lost_ref = diff(after, refd)
    for e in rerr:
        fail("replay: " + e)
    # The oracle can fail: the same replay of one model without one of its
    # acknowledged operations (its last upload), and of a solved model with
    # one upload that is in its final data changed by 1e-4 in T, must each
    # differ from the soaked daemon's state (the second in the data: nets,
    # grids, queries, not only the counters of the status block).
    sens = {}
    cand = [u for u in range(1, WRITERS + 1) if any(op[0] == "up" for op, _ in LOGS[u].ops)]
    solved = [u for u in cand if after[u]["status"][1] == 2]
    cases = []
    if cand:
        u = rnd.choice(cand)
        ops = list(LOGS[u].ops)
        k = max(i for i, (op, _) in enumerate(ops) if op[0] == "up")
        del ops[k]
        cases.append(("drop", u, k, ops))
    if solved:
        u = rnd.choice(solved)
        ops = list(LOGS[u].ops)
        start_k = max([i for i, (op, _) in enumerate(ops) if op[0] == "cfg" or op == ("cmd", 2)] + [-1])
        k = None
        for i in range(len(ops) - 1, start_k, -1):
            op = ops[i][0]
            if op[0] == "up":
                k = i
                break
        if k is not None:
            regs = list(ops[k][0][1])
            regs[9] = regs[9] + 1 if regs[9] < 10000 else regs[9] - 1
            ops[k] = (("up", tuple(regs)), None)
            cases.append(("change", u, k, ops))
    for kind, u, k, ops in cases:
        ref2 = Daemon(args.it2nd, tmp, "reference-%s" % kind)
        ref2.start(conf_text(os.path.join(tmp, "ref-%s-state" % kind), ref_port, tmp, idle[0], links=False,
                             fsync=False), " ready (")
        replay(ref_port, units=[u], logs={u: ops}, check_keys=False)
        d_minus = diff(after, dump(ref_port, "reference-" + kind, units=[u]), units=[u])
        ref2.stop()
        data = [x for x in d_minus if " status " not in x]
        sens[kind] = {"unit": u, "op_index": k, "of": len(LOGS[u].ops), "differences": len(d_minus),
                      "in_data": len(data), "first": d_minus[:3]}
        if not d_minus or (kind == "change" and not data):
            fail("sensitivity (%s): replaying unit %d with operation %d %s gave the same state: the comparison "
                 "would not see it" % (kind, u, k, "dropped" if kind == "drop" else "changed"))
        else:
            R.ok("sensitivity: unit %d replayed with acknowledged operation %d of %d %s: %d difference(s), e.g. %s"
                 % (u, k, len(LOGS[u].ops), "dropped" if kind == "drop" else "changed by 1e-4 in T",
                    len(d_minus), (data or d_minus)[0]))
    if "drop" not in sens:
        R.skip("sensitivity (drop): no writer model has an acknowledged upload to drop")
    if "change" not in sens:
        R.skip("sensitivity (change): no writer model solved at the end: the data check was not run")

    # ---- RSS and fds ----
    last = incarnations[-1]["samples"]
    warm_s = 15 if args.seconds >= 120 else 5
    warm = [s for s in last if s[0] >= warm_s]
    rss_growth = fd_growth = None
    if len(warm) >= 10:
        w = min(10, len(warm) // 3)
        rss_growth = statistics.median(s[1] for s in warm[-w:]) - statistics.median(s[1] for s in warm[:w])
        fd_growth = statistics.median(s[2] for s in warm[-w:]) - statistics.median(s[2] for s in warm[:w])
        R.check(rss_growth <= args.rss_tol_kib, "RSS growth %d KiB over %.0f s of the last incarnation "
                "(tolerance %d KiB)" % (rss_growth, warm[-1][0] - warm[0][0], args.rss_tol_kib))
        R.check(fd_growth <= FD_TOL, "fd count growth %d (tolerance %d)" % (fd_growth, FD_TOL))
    else:
        fail("last incarnation too short to measure RSS/fd growth (%d samples after warm-up)" % len(warm))
    per_inc = []
    for k, inc_ in enumerate(incarnations):
        sm = inc_["samples"]
        if sm:
            per_inc.append({"incarnation": k + 1, "fault_site": inc_["fault"], "fsync_delay_ms": inc_["delay"],
                            "seconds": round(sm[-1][0], 1),
                            "rss_kib_first": sm[0][1], "rss_kib_max": max(s[1] for s in sm),
                            "rss_kib_last": sm[-1][1], "fds_first": sm[0][2], "fds_max": max(s[2] for s in sm),
                            "fds_last": sm[-1][2]})

    ops = sum(len(LOGS[u].ops) for u in UNITS)
    unexpected = len(ST.unexpected)
    lost = len(lost_kill) + len(lost_ref) + len(rerr) + sum(1 for f in FAILS if "lost" in f or "neither" in f)
    c = dict(ST.c)
    summary = {
        "seconds": args.seconds, "seed": seed, "kills": kills, "sighups": hups, "fault_windows": faults,
        "power_cuts": len(powercuts), "power_cuts_torn": sum(1 for p in powercuts if p["torn"]),
        "power_cut_namespace_ops_undone": sum(p["ops_pending"] - p["ops_kept"] for p in powercuts),
        "daemon_crashes": crashed, "operations_logged": ops,
        "operations_per_model": {str(u): len(LOGS[u].ops) for u in UNITS},
        "counters": c, "unexpected_failures": ST.unexpected[:50],
        "store_degraded_log_lines": log_text.count("store degraded"),
        "checkpoints_recovered": log_text.count("writes accepted again"),
        "snapshot_failures_logged": log_text.count("snapshot failed"),
        "reloads_logged": log_text.count("reload"),
        "rss_growth_kib": rss_growth, "fd_growth": fd_growth,
        "rss_tolerance_kib": args.rss_tol_kib, "it2nd": args.it2nd, "fd_tolerance": FD_TOL,
        "incarnations": per_inc, "failures": FAILS[:50], "sensitivity_check": sens,
        "instrument_failures": ST.known[:20],
    }

    def row(name, unit, value, target, met):
        return {"name": name, "unit": unit, "value": value, "baseline": None, "ratio": None,
                "target": target, "met": met}
    rows = [
        row("soak lost acknowledged operations", "operations", lost, 0, lost == 0),
        row("soak unexpected failed requests", "requests", unexpected, 0, unexpected == 0),
        row("soak daemon RSS growth after warm-up", "KiB", rss_growth, args.rss_tol_kib,
            rss_growth is not None and rss_growth <= args.rss_tol_kib),
        row("soak daemon fd growth after warm-up", "fds", fd_growth, FD_TOL,
            fd_growth is not None and fd_growth <= FD_TOL),
        row("soak acknowledged operations replayed", "operations", ops, None, None),
        row("soak kill -9 restarts", "count", kills, None, None),
        row("soak power cuts (state rolled back to its durable image)", "count", len(powercuts), None, None),
        row("soak duration", "s", args.seconds, None, None),
    ]
    result = {"rows": rows, "soak": summary, "conditions": {
        "cpus": os.cpu_count(), "loadavg_1min": round(os.getloadavg()[0], 2),
        "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "note": "tests/soak/soak.py: %d writers, %d readers (Modbus TCP), %d instrument links, SIGHUP every 2-5 s, "
                "kill -9 every 6-20 s in the first 60 %%%s, failio.so faults"
                % (WRITERS, READERS, len(LINKS), " (each a power cut: powercut.so)" if args.powercut else "")}}
    if args.out:
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        with open(args.out, "w") as f:
            json.dump(result, f, indent=2, sort_keys=True)
            f.write("\n")
    say("%d operations logged over %d models, %d kills (%d power cuts), %d SIGHUPs, %d fault windows; counters %s"
        % (ops, len(UNITS), kills, len(powercuts), hups, faults, json.dumps(c, sort_keys=True)))
    R.check(lost == 0, "zero acknowledged operations lost (%d logged over %d models, %d kills, %d power cuts)"
            % (ops, len(UNITS), kills, len(powercuts)), "%d lost, e.g. %s" % (lost, (lost_kill + lost_ref + rerr)[:3]))
    R.check(unexpected == 0, "zero unexpected failed requests", "%d, e.g. %s" % (unexpected, ST.unexpected[:3]))
    if args.keep and not R.fails:
        say("logs kept in %s (--keep)" % tmp)
    else:
        R.tidy(tmp)
    sys.exit(R.finish())


def cleanup():
    """Whatever happens, stop what this run started (by pid)."""
    STOP.set()
    for p in list(STARTED):
        if p.poll() is None:
            p.kill()
            p.wait()


STARTED = []


if __name__ == "__main__":
    import atexit
    atexit.register(cleanup)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # timeout(1): clean up too
    main()
