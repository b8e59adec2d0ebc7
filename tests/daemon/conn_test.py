#!/usr/bin/python3
"""conn_test.py -- connection slots, RTU inter-frame silence and access
control, tested against the real it2nd process (loopback and ptys only).

  conn_test.py --it2nd BIN [--out JSON] [--only slots,emfile,rtu,acl] [--quick]

Every daemon this script starts is stopped before it exits; figures go to
the JSON file (--out, merged into what is there). Exit status 0 when every
check passed. See docs/daemon.md ("Connection slots", "RTU framing",
"Access control") for the guarantees checked here.
"""
import argparse
import json
import os
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import termios
import threading
import time
import tty

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import daemon as it2nd_proc  # noqa: E402
from it2ntest import report  # noqa: E402
from it2ntest.modbus import connect, mbap, read_regs, write_regs  # noqa: E402  (admit and slowdisk use them too)
from it2ntest.modbus import request as tcp_request  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

R = report.Report("conn")  # admit_test.py, which imports these helpers, renames it
ok, fail, check = R.ok, R.fail, R.check
FIGS = {}


class Daemon(it2nd_proc.Daemon):
    """One it2nd process on a configuration written to tmp."""

    def __init__(self, binary, tmp, name):
        super().__init__(binary, os.path.join(tmp, name + ".conf"), os.path.join(tmp, name + ".log"), name=name)
        self.tmp = tmp

    def write(self, text):
        self.write_conf(text)

    def start(self, text, ready, prefix=(), nofile=None, verbose=True):
        """Write text as its configuration, start it, return once ready is
        in its log."""
        self.write(text)
        limit = None
        if nofile:
            import resource

            def limit():
                resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))
        self.args = ["-v"] if verbose else []
        super().start(ready=ready, prefix=prefix, preexec_fn=limit)

    def stop(self):
        rc = super().stop()
        self.proc = None
        return 0 if rc is None else rc


# ---- Modbus TCP -------------------------------------------------------------

def closed_by_peer(s, wait=0.0):
    """True when the daemon closed s (EOF or reset) within wait seconds."""
    s.settimeout(wait if wait > 0 else 0.001)
    try:
        return s.recv(16) == b""
    except socket.timeout:
        return False
    except BlockingIOError:
        return False
    except OSError:
        return True


def proc_tcp_timer(local_port, remote_port):
    """(timer kind, seconds) of the daemon's end of a loopback connection
    from /proc/net/tcp: kind 2 is the keepalive timer."""
    with open("/proc/net/tcp") as f:
        next(f)
        for line in f:
            fld = line.split()
            lp = int(fld[1].split(":")[1], 16)
            rp = int(fld[2].split(":")[1], 16)
            if lp == local_port and rp == remote_port and fld[3] == "01":
                kind, when = fld[5].split(":")
                return int(kind, 16), int(when, 16) / os.sysconf("SC_CLK_TCK")
    return None


def unit_kw(fn, unit):
    """pymodbus 3.0.0 takes unit=, its 3.0.0rc1 (Debian 12) slave=."""
    import inspect
    return {"slave" if "slave" in inspect.signature(fn).parameters else "unit": unit}


def pymodbus_read(port, unit=1):
    """A real client (pymodbus 3.0): connect and read the status block.
    Returns the seconds from connect to the answer, or None."""
    import logging
    from pymodbus.client import ModbusTcpClient
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    t0 = time.monotonic()
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
    try:
        if not c.connect():
            return None
        r = c.read_input_registers(0, 2, **unit_kw(c.read_input_registers, unit))
        if r.isError() or list(r.registers) != [1, 2]:
            return None
        return time.monotonic() - t0
    except Exception:  # pymodbus raises its own exception types
        return None
    finally:
        c.close()


class Holder(threading.Thread):
    """Holds one slot: 'idle' connects and says nothing; 'slowloris'
    dribbles a request one byte per 100 ms. Either reconnects as soon as
    the daemon closes it (an attacker that keeps trying)."""

    def __init__(self, port, kind):
        super().__init__(daemon=True)
        self.port, self.kind = port, kind
        self.stop = threading.Event()
        self.closes = 0
        self.sock = None

    def run(self):
        req = mbap(7, 1, struct.pack(">BHH", 4, 0, 2))
        while not self.stop.is_set():
            try:
                s = connect(self.port, timeout=1)
            except OSError:
                time.sleep(0.05)
                continue
            self.sock = s
            k = 0
            while not self.stop.is_set():
                if self.kind == "slowloris":
                    try:
                        s.sendall(req[k % (len(req) - 1):k % (len(req) - 1) + 1])
                    except OSError:
                        break
                    k += 1
                if closed_by_peer(s, 0.1):
                    self.closes += 1
                    break
            s.close()


def test_slots(args):
    port = free_port()
    d = Daemon(args.it2nd, args.tmp, "slots")
    # Defaults for everything but the address: the guarantees hold as shipped.
    conf = ("[daemon]\nstate_dir = %s/state_slots\nsnapshot_interval = 3600\nfsync = no\n"
            "[modbus]\ntcp_listen = 127.0.0.1:%d\n[model:1]\nunit_id = 1\npreload = paper\n" % (args.tmp, port))
    d.start(conf, "ready")
    try:
        # Keepalive on accepted sockets (default tcp_keepalive = 60 s).
        s = connect(port)
        read_regs(s, 1, 0, 2)
        t = proc_tcp_timer(port, s.getsockname()[1])
        check(t is not None and t[0] == 2 and 45 <= t[1] <= 60.5,
              "accepted socket has TCP keepalive armed (60 s)", "timer %r" % (t,))
        s.close()

        # A half-sent request (8 of 12 bytes) is closed within 1 s.
        s = connect(port)
        t0 = time.monotonic()
        s.sendall(mbap(1, 1, struct.pack(">BHH", 4, 0, 2))[:8])
        closed = closed_by_peer(s, 3.0)
        dt = time.monotonic() - t0
        check(closed and dt <= 1.0, "half-sent request closed in %.0f ms (<= 1 s)" % (dt * 1000))
        s.close()
        # Slowloris: one byte every 100 ms never completes a request.
        s = connect(port)
        t0 = time.monotonic()
        req = mbap(1, 1, struct.pack(">BHH", 4, 0, 2))
        closed = False
        for k in range(30):
            try:
                s.sendall(req[k % 11:k % 11 + 1])
            except OSError:
                closed = True
                break
            if closed_by_peer(s, 0.1):
                closed = True
                break
        dt = time.monotonic() - t0
        check(closed and dt <= 1.1, "slowloris (1 byte/100 ms) closed %.0f ms after its first byte" % (dt * 1000))
        s.close()

        # 32 connections that never sent a byte hold no slot: a new client
        # is served at once and none of them is closed for it.
        held = [connect(port) for _ in range(32)]
        time.sleep(0.8)
        times = [pymodbus_read(port) for _ in range(3)]
        evicted = sum(closed_by_peer(h) for h in held)
        good = all(x is not None and x <= 1.0 for x in times)
        check(good and evicted == 0,
              "32 connections that sent nothing: pymodbus served in %s ms, %d of them closed (they hold no slot)"
              % ("/".join("%.0f" % (x * 1000) if x else "-" for x in times), evicted))
        FIGS["lockout_idle_ms"] = [round(x * 1000, 1) if x else None for x in times]
        for h in held:
            h.close()
        # max_clients (32) clients that each sent one request, then went
        # idle, hold every slot: a new client is served within 1 s, the
        # one idle longest gives up its slot.
        held = []
        for k in range(32):
            h = connect(port)
            read_regs(h, 1, 0, 2, k + 1)
            held.append(h)
        time.sleep(0.8)
        times = [pymodbus_read(port) for _ in range(3)]
        gone = [k for k, h in enumerate(held) if closed_by_peer(h)]
        good = all(x is not None and x <= 1.0 for x in times)
        # The first newcomer takes the slot of the longest-idle client (the
        # first to connect); the next ones find it free again (pymodbus closed).
        check(good and gone == [0],
              "32 slots held by idle clients: pymodbus served in %s ms, the client idle longest evicted (%s)"
              % ("/".join("%.0f" % (x * 1000) if x else "-" for x in times), gone))
        FIGS["lockout_slots_ms"] = [round(x * 1000, 1) if x else None for x in times]
        for h in held:
            h.close()
        time.sleep(0.2)

        # The same against attackers that reconnect at once: 32 idle, then
        # 32 slowloris holders.
        for kind in ("idle", "slowloris"):
            hs = [Holder(port, kind) for _ in range(32)]
            for h in hs:
                h.start()
            time.sleep(1.2)
            times = []
            for _ in range(5):
                times.append(pymodbus_read(port))
                time.sleep(0.2)
            for h in hs:
                h.stop.set()
            for h in hs:
                h.join()
            good = all(x is not None and x <= 1.0 for x in times)
            check(good, "32 reconnecting %s holders: a new client served in %s ms" %
                  (kind, "/".join("%.0f" % (x * 1000) if x else "-" for x in times)))
            FIGS["lockout_%s_reconnecting_ms" % kind] = [round(x * 1000, 1) if x else None for x in times]
            time.sleep(0.6)

        # 500 connection attempts beyond the limit change nothing for the
        # 32 connected clients, which poll all along on the same connection.
        flood(port)
    finally:
        rc = d.stop()
        check(rc == 0, "daemon (slots) exits 0", "rc %s" % rc)


def cpu_seconds(pid):
    with open("/proc/%d/stat" % pid) as f:
        fld = f.read().rsplit(")", 1)[1].split()
    return (int(fld[11]) + int(fld[12])) / os.sysconf("SC_CLK_TCK")


def test_emfile(args):
    """Out of descriptors (RLIMIT_NOFILE 32 < max_clients): the daemon
    neither spins on accept() nor stops serving, and accepts again once
    descriptors are free."""
    port = free_port()
    d = Daemon(args.it2nd, args.tmp, "emfile")
    conf = ("[daemon]\nstate_dir = %s/state_emfile\nsnapshot_interval = 3600\nfsync = no\n"
            "[modbus]\ntcp_listen = 127.0.0.1:%d\n[model:1]\nunit_id = 1\npreload = paper\n" % (args.tmp, port))
    d.start(conf, "ready", nofile=32)
    try:
        first = connect(port)
        read_regs(first, 1, 0, 2)
        # Connections with a complete request: once in a slot they are not
        # pushed out for newcomers, so the descriptors run out.
        socks = []
        for k in range(40):
            try:
                x = connect(port, timeout=1)
            except OSError:
                break
            socks.append(x)
            try:
                x.sendall(mbap(k + 1, 1, struct.pack(">BHH", 4, 0, 2)))
            except OSError:
                pass
        time.sleep(0.3)
        c0 = cpu_seconds(d.proc.pid)
        time.sleep(1.0)
        cpu = cpu_seconds(d.proc.pid) - c0
        served = read_regs(first, 1, 0, 2) == (1, 2)
        logged = d.wait_log("tcp accept: Too many open files; listeners paused for 100 ms", 2) and \
            "tcp: RLIMIT_NOFILE 32 (hard 32) leaves room for 4 pending connections, not max_pending 1024" \
            in d.logtext()
        for x in socks:
            x.close()
        time.sleep(0.5)
        later = pymodbus_read(port)
        check(cpu < 0.3 and served and logged and later is not None,
              "out of descriptors: %.2f s CPU in 1 s (no accept() spin), connected client served, "
              "EMFILE and the pending places RLIMIT_NOFILE leaves logged, a new client served once descriptors "
              "are free" % cpu,
              "cpu %.2f served %s logged %s later %r" % (cpu, served, logged, later))
        FIGS["emfile_cpu_s_per_s"] = round(cpu, 3)
        first.close()
    finally:
        rc = d.stop()
        check(rc == 0, "daemon (emfile) exits 0", "rc %s" % rc)


def flood(port):
    stop = threading.Event()
    stats = {"polls": 0, "fails": [], "lat": []}
    lock = threading.Lock()
    socks = [connect(port) for _ in range(32)]

    def poller(k, s):
        tid = 0
        while not stop.is_set():
            tid = (tid + 1) & 0xFFFF
            t0 = time.monotonic()
            try:
                r = read_regs(s, 1, 0, 2, tid)
            except (OSError, ValueError) as e:
                with lock:
                    stats["fails"].append("client %d: %s" % (k, e))
                return
            dt = time.monotonic() - t0
            with lock:
                stats["polls"] += 1
                stats["lat"].append(dt)
                if r != (1, 2):
                    stats["fails"].append("client %d: read %r" % (k, r))
            time.sleep(0.05)

    threads = [threading.Thread(target=poller, args=(k, s), daemon=True) for k, s in enumerate(socks)]
    for t in threads:
        t.start()
    time.sleep(0.3)
    counts = {"close": 0, "partial": 0, "garbage": 0, "idle": 0, "request": 0, "answered": 0}
    req = mbap(9, 1, struct.pack(">BHH", 4, 0, 2))

    def attempt(k):
        kind = ("close", "partial", "garbage", "idle", "close", "partial", "garbage", "idle", "request")[k % 9]
        try:
            s = connect(port, timeout=2)
        except OSError:
            return
        with lock:
            counts[kind] += 1
        try:
            if kind == "partial":
                s.sendall(req[:5])
            elif kind == "idle":
                time.sleep(0.5)  # holds no slot: nothing to wait for
            elif kind == "garbage":
                s.sendall(b"GET / HTTP/1.0\r\n\r\n")
            elif kind == "request":
                s.sendall(req)
            if kind not in ("close", "idle"):
                s.settimeout(2.0)
                try:
                    got = s.recv(64)
                    if kind == "request" and got:
                        with lock:
                            counts["answered"] += 1
                except OSError:
                    pass
        finally:
            s.close()

    t0 = time.monotonic()
    pool = []
    for k in range(500):
        th = threading.Thread(target=attempt, args=(k,), daemon=True)
        th.start()
        pool.append(th)
        if len(pool) >= 120:
            pool.pop(0).join()
    for th in pool:
        th.join()
    flood_s = time.monotonic() - t0
    time.sleep(0.3)
    stop.set()
    for t in threads:
        t.join()
    alive = sum(not closed_by_peer(s) for s in socks)
    for s in socks:
        s.close()
    lat = sorted(stats["lat"])
    p99 = lat[int(len(lat) * 0.99)] * 1000 if lat else -1
    check(not stats["fails"] and alive == 32 and counts["answered"] == 0,
          "500 connection attempts (%s) in %.1f s: 32 connected clients kept their connections, "
          "%d polls all answered (max %.1f ms, p99 %.1f ms); no attempt took a slot in use"
          % (", ".join("%d %s" % (v, k) for k, v in counts.items() if k != "answered"), flood_s,
             stats["polls"], lat[-1] * 1000 if lat else -1, p99),
          "fails %s, alive %d, answered %d" % (stats["fails"][:3], alive, counts["answered"]))
    FIGS["flood_500"] = {"attempts": {k: v for k, v in counts.items() if k != "answered"},
                         "seconds": round(flood_s, 2), "client_polls": stats["polls"],
                         "client_failures": len(stats["fails"]),
                         "client_latency_max_ms": round(lat[-1] * 1000, 2) if lat else None,
                         "client_latency_p99_ms": round(p99, 2)}


# ---- Modbus RTU on ptys -------------------------------------------------------

def crc16(b):
    crc = 0xFFFF
    for x in b:
        crc ^= x
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def rtu(b):
    c = crc16(b)
    return bytes(b) + bytes([c & 0xFF, c >> 8])


class Line:
    """The master's end of a pty whose other end the daemon serves."""

    def __init__(self):
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)

    def drain(self, wait=0.0):
        import select
        got = b""
        deadline = time.monotonic() + wait
        while True:
            left = deadline - time.monotonic()
            r, _, _ = select.select([self.master], [], [], max(left, 0))
            if not r:
                return got
            got += os.read(self.master, 4096)

    def ask(self, frames, gaps, want_len, timeout=1.0):
        """Write frames with the given pauses (s) between them; return the
        bytes answered (up to want_len) and the seconds from the last write."""
        import select
        for k, f in enumerate(frames):
            if k:
                t_end = time.monotonic() + gaps[k - 1]
                while time.monotonic() < t_end:  # busy-wait: sleep() may oversleep by ms
                    pass
            t0 = time.monotonic()
            os.write(self.master, f)
        got = b""
        while len(got) < want_len:
            left = t0 + timeout - time.monotonic()
            r, _, _ = select.select([self.master], [], [], max(left, 0))
            if not r:
                break
            got += os.read(self.master, 4096)
        return got, time.monotonic() - t0

    def wait_for(self, frames, want, timeout=1.0):
        """Write frames at once; the seconds until the bytes `want` have
        arrived (anything before them is skipped), or None."""
        import select
        t0 = time.monotonic()  # before the write: the daemon may run before write() returns
        os.write(self.master, b"".join(frames))
        got = b""
        while want not in got:
            left = t0 + timeout - time.monotonic()
            r, _, _ = select.select([self.master], [], [], max(left, 0))
            if not r:
                return None
            got += os.read(self.master, 4096)
        return time.monotonic() - t0

    def close(self):
        os.close(self.master)
        os.close(self.slave)


# A master polling other slaves on the same bus, as our port sees it.
FOREIGN = [
    ("FC03 request to unit 2 and its 6-byte reply",
     [rtu([2, 3, 0, 0, 0, 3]), rtu([2, 3, 6, 0, 1, 0, 2, 0, 3])]),
    ("FC16 request to unit 2 and its reply",
     [rtu([2, 16, 0, 40, 0, 2, 4, 0, 1, 0, 2]), rtu([2, 16, 0, 40, 0, 2])]),
    ("FC01 request to unit 9 and its reply",
     [rtu([9, 1, 0, 0, 0, 16]), rtu([9, 1, 2, 0xFF, 0])]),
    ("exception reply of unit 2", [rtu([2, 3, 0, 0, 0, 3]), rtu([2, 0x83, 2])]),
    ("FC03 reply of 240 bytes from unit 5", [rtu([5, 3, 0, 0, 0, 120]), rtu([5, 3, 240] + list(range(240)))]),
    ("a frame with a CRC error", [rtu([2, 4, 0, 0, 0, 2])[:-1] + b"\x00"]),
    ("FC16 reply of unit 2 cut short", [rtu([2, 16, 0, 40, 0, 12])[:5]]),
]
REQ = rtu([1, 4, 0, 0, 0, 2])           # map_version, state
ANS = rtu([1, 4, 4, 0, 1, 0, 2])


def foreign_rounds(line, rounds, gap):
    """rounds x (foreign frames 2 ms apart, `gap` s of silence, our
    request): returns (answered, wrong, gaps measured)."""
    answered, wrong = 0, []
    for k in range(rounds):
        name, frames = FOREIGN[k % len(FOREIGN)]
        got, _ = line.ask(frames + [REQ], [0.002] * (len(frames) - 1) + [gap], len(ANS))
        got += line.drain(0.003)
        if got == ANS:
            answered += 1
        else:
            wrong.append("%s: %s" % (name, got.hex()))
    return answered, wrong


def test_rtu(args):
    fast, slow = Line(), Line()
    d = Daemon(args.it2nd, args.tmp, "rtu")
    conf = ("[daemon]\nstate_dir = %s/state_rtu\nsnapshot_interval = 3600\nfsync = no\n"
            "[modbus]\ntcp_listen = none\n[model:1]\nunit_id = 1\npreload = paper\n"
            "[rtu:fast]\ndevice = %s\nbaud = 115200\nparity = none\n"
            "[rtu:slow]\ndevice = %s\nbaud = 9600\nread_only = yes\n" % (args.tmp, fast.path, slow.path))
    try:
        d.start(conf, "modbus rtu slow")
        time.sleep(0.2)
        check("modbus rtu fast on %s, 115200 N1, RS-232, t3.5 1750 us" % fast.path in d.logtext()
              and "modbus rtu slow on %s, 9600 E1, RS-232, t3.5 4011 us" % slow.path in d.logtext(),
              "t3.5 from the baud rate: 1750 us at 115200, 4011 us at 9600 8E1 (logged)")
        # A request 5 ms after another slave's frame, every time.
        rounds = 210 if not args.quick else 70
        n, wrong = foreign_rounds(fast, rounds, 0.005)
        check(n == rounds, "115200 Bd: a request 5 ms after a foreign frame answered %d/%d times "
              "(%d kinds of foreign traffic)" % (n, rounds, len(FOREIGN)), "; ".join(wrong[:4]))
        FIGS["rtu_115200_after_foreign_5ms"] = {"answered": n, "rounds": rounds}
        n, wrong = foreign_rounds(slow, 35, 0.006)
        check(n == 35, "9600 Bd: a request 6 ms (> t3.5 = 4.0 ms) after a foreign frame answered %d/35" % n,
              "; ".join(wrong[:4]))
        # Silence not seen (one read holds both): the request still found.
        n = 0
        for k in range(len(FOREIGN)):
            got, _ = fast.ask([b"".join(FOREIGN[k][1]) + REQ], [], len(ANS))
            n += (got + fast.drain(0.003)) == ANS
        check(n == len(FOREIGN), "a request right behind a foreign frame in one read answered %d/%d" %
              (n, len(FOREIGN)))
        # CRC errors are never answered; the next request is.
        bad = REQ[:-1] + bytes([REQ[-1] ^ 0x55])
        got, _ = fast.ask([bad], [], 1, timeout=0.05)
        got2, _ = fast.ask([bad, REQ], [0.005], len(ANS))
        check(got == b"" and got2 + fast.drain(0.003) == ANS,
              "a request with a CRC error is ignored, the next one 5 ms later answered",
              "%s / %s" % (got.hex(), got2.hex()))
        # The silence is detected within a fraction of t3.5: a function the
        # daemon does not frame by length is answered (exception 01) once
        # t3.5 has passed, not before.
        # Functions the daemon does not serve, rotated so that a reply late
        # from an earlier round (a stalled machine) is never taken for this
        # round's.
        fcs = (17, 20, 21, 43, 7, 8, 11, 12, 24, 1, 2, 5, 15, 22)
        for line, t35, name in ((fast, 1.75e-3, "115200"), (slow, 4.011e-3, "9600")):
            lat = []
            for k in range(40):
                fc = fcs[k % len(fcs)]
                dt = line.wait_for([rtu([1, fc])], rtu([1, 0x80 | fc, 1]))
                if dt is not None:
                    lat.append(dt)
                line.drain(0.002)
            lat.sort()
            med = statistics.median(lat) if lat else 1
            # The reply is written after t3.5 plus the detection delay:
            # reply - t3.5 is the upper bound of the detection delay.
            # Loose bound on a shared machine (the exact threshold is checked
            # with a fake clock by fuzz_rtu); the old fixed 20 ms floor fails.
            check(len(lat) == 40 and lat[0] >= t35 and med < 0.010,
                  "%s Bd: unknown function answered after the silence: min %.2f ms >= t3.5 %.2f ms, "
                  "median %.2f ms (detection <= %.2f ms)" % (name, lat[0] * 1e3 if lat else -1, t35 * 1e3,
                                                            med * 1e3, (med - t35) * 1e3),
                  "%d answers" % len(lat))
            FIGS["rtu_%s_silence_reply_ms" % name] = {
                "t35_ms": round(t35 * 1e3, 3), "min": round(lat[0] * 1e3, 3) if lat else None,
                "median": round(med * 1e3, 3), "max": round(lat[-1] * 1e3, 3) if lat else None}
        # A read-only port: an upload gets exception 02, query writes work;
        # the same upload on the other port is accepted.
        up = rtu([1, 16, 0, 40, 0, 12, 24] + [b for v in UP_D00 for b in (v >> 8, v & 0xFF)])
        q = rtu([1, 6, 0, 64, 0x13, 0x88])
        got_ro, _ = slow.ask([up], [], 5)
        got_q, _ = slow.ask([q], [], 8)
        got_rw, _ = fast.ask([up], [], 8)
        check(got_ro == rtu([1, 0x90, 2]) and got_q == q and got_rw == rtu([1, 16, 0, 40, 0, 12]),
              "[rtu:] read_only = yes: upload refused with exception 02, query write echoed; "
              "the read-write port takes the upload", "%s %s %s" % (got_ro.hex(), got_q.hex(), got_rw.hex()))
    finally:
        rc = d.stop()
        check(rc == 0, "daemon (rtu) exits 0", "rc %s" % rc)
        fast.close()
        slow.close()


# ---- access control -------------------------------------------------------------

UP_D00 = [0, 0, 3, 65535, 63836, 0, 1700, 0, 0, 4000, 7000, 2000]  # paper point (0,0,D), as uploaded


def has_ipv6():
    try:
        s = socket.socket(socket.AF_INET6)
        s.bind(("::1", 0))
        s.close()
        return True
    except OSError:
        return False


def refused_at_once(port, src=None, host="127.0.0.1"):
    """Connect and send a request: True when the daemon closes the
    connection without answering."""
    try:
        s = connect(port, host=host, src=src)
    except OSError:
        return True
    try:
        s.sendall(mbap(1, 1, struct.pack(">BHH", 4, 0, 2)))
        s.settimeout(2)
        return s.recv(64) == b""
    except OSError:
        return True
    finally:
        s.close()


def mbpoll(port, unit, addr, values=(), count=1):
    cmd = ["mbpoll", "-m", "tcp", "-a", str(unit), "-0", "-r", str(addr), "-t", "4", "-1", "-o", "2",
           "-p", str(port)]
    if not values:
        cmd[-2:-2] = ["-c", str(count)]
    cmd += ["127.0.0.1"] + [str(v) for v in values]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=20)
    return r.returncode, r.stdout + r.stderr


def pymodbus_query(port, unit, u, w):
    """FC 23: write (u, w) x10000 to 64..65, read the D footprint's scaled
    T, I, F (256 + 3*9 + 6) in one transaction; the values or None."""
    import logging
    from pymodbus.client import ModbusTcpClient
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
    try:
        if not c.connect():
            return None
        r = c.readwrite_registers(read_address=256 + 3 * 9 + 6, read_count=3, write_address=64,
                                  write_registers=[u, w], **unit_kw(c.readwrite_registers, unit))
        return None if r.isError() else list(r.registers)
    except Exception:
        return None
    finally:
        c.close()


def generation(s, unit):
    r = read_regs(s, unit, 7, 2, fc=3)
    return r[0] << 16 | r[1]


def acl_conf(args, p, v6, eng_allow="allow = 127.0.0.2\nallow = 127.0.1.0/24, ::1\n", plc_ro="yes"):
    text = ("[daemon]\nstate_dir = %s/state_acl\nsnapshot_interval = 3600\nfsync = no\n"
            "[listen:eng]\naddress = 127.0.0.1:%d\n%s"
            "[listen:plc]\naddress = 127.0.0.1:%d\nread_only = %s\n" % (args.tmp, p[0], eng_allow, p[1], plc_ro))
    if v6:
        text += ("[listen:v6]\naddress = [::1]:%d\nallow = ::1/128\n"
                 "[listen:v6other]\naddress = [::1]:%d\nallow = fe80::/10\n" % (p[2], p[3]))
    return text + ("[model:1]\nunit_id = 1\npreload = paper\n"
                   "[model:2]\nunit_id = 2\npreload = paper\nwrite_protect = yes\n")


def test_acl(args):
    v6 = has_ipv6()
    p = [free_port() for _ in range(4)]
    d = Daemon(args.it2nd, args.tmp, "acl")
    try:
        d.start(acl_conf(args, p, v6), "ready")
        # Allow-lists: addresses and prefixes, IPv4 and IPv6.
        s = connect(p[0], src="127.0.0.2")
        check(read_regs(s, 1, 0, 2) == (1, 2) and write_regs(s, 1, 40, UP_D00) == "ok",
              "listener eng: 127.0.0.2 (allow-listed address) reads and writes")
        s.close()
        s = connect(p[0], src="127.0.1.7")
        check(read_regs(s, 1, 0, 2) == (1, 2), "listener eng: 127.0.1.7 inside allow 127.0.1.0/24 served")
        s.close()
        check(refused_at_once(p[0], src="127.0.0.3") and refused_at_once(p[0], src="127.0.2.1"),
              "listener eng: 127.0.0.3 and 127.0.2.1 (not listed) closed without an answer")
        check(d.wait_log("refused: not in the allow-list of listener eng 127.0.0.1:%d" % p[0]),
              "refusal logged with the listener's name")
        if v6:
            s = connect(p[2], host="::1")
            check(read_regs(s, 1, 0, 2) == (1, 2) and refused_at_once(p[3], host="::1"),
                  "IPv6: ::1 served by allow ::1/128, refused by allow fe80::/10")
            s.close()
        else:
            print("conn: skip: no IPv6 loopback here")

        # Read-only listener: reads and queries work, model changes do not.
        rc, out = mbpoll(p[1], 1, 0, count=2)
        ok_read = rc == 0 and "[1]: \t2" in out.replace(" ", " ") or (rc == 0 and "[1]:" in out)
        # A refused upload on the read-write listener sets the model's
        # last_error (-2, T out of range at i 0, j 0, fp 3); refusals on the
        # read-only listener below must leave it as it is (issue 20 item 6).
        watch = connect(p[0], src="127.0.0.2")
        bad_t = write_regs(watch, 1, 40, UP_D00[:9] + [12000, 7000, 2000])
        err0 = read_regs(watch, 1, 9, 4)
        s = connect(p[1])
        g0 = generation(s, 1)
        rc, out = mbpoll(p[1], 1, 40, UP_D00[:9] + [4500, 7000, 2000])
        refused = rc != 0 and "Illegal data address" in out
        r06 = tcp_request(s, 1, struct.pack(">BHH", 6, 35, 2))          # CLEAR command
        r23 = tcp_request(s, 1, struct.pack(">BHHHHB", 23, 0, 2, 32, 3, 6) + struct.pack(">3H", 2, 2, 0))
        q = pymodbus_query(p[1], 1, 5000, 5000)
        g1 = generation(s, 1)
        check(ok_read and refused and r06 == ("exc", 2) and r23 == ("exc", 2) and q == [6738, 4645, 1617]
              and g1 == g0 and read_regs(s, 1, 1, 1) == (2,),
              "read-only listener: mbpoll reads; mbpoll upload (FC16), CLEAR (FC06) and a configuration "
              "by FC23 get exception 02; a pymodbus FC23 query answers [6738, 4645, 1617]; generation %d unchanged"
              % g0, "read %s refused %s 06 %r 23 %r query %r gen %d->%d: %s" % (ok_read, refused, r06, r23, q, g0, g1,
                                                                              out[-200:]))
        check(d.wait_log("write to unit 1 registers 40..51 refused: read-only listener"),
              "refused write logged (first per connection at notice level)")
        err1 = read_regs(watch, 1, 9, 4)
        check(bad_t == ("exc", 3) and err0 == (0xFFFE, 0, 0, 3) and err1 == err0,
              "read-only refusals are the requester's alone: another client reads last_error %d (i %d, j %d, "
              "fp %d) of its own refused upload before and after them" % (err0[0] - 65536 if err0[0] > 32767
                                                                         else err0[0], err0[1], err0[2], err0[3]),
              "upload %r, status before %r, after %r" % (bad_t, err0, err1))
        watch.close()

        # Per-unit write protection: unit 2 refuses model changes on every
        # listener, queries still work; unit 1 on the same connection writes.
        s2 = connect(p[0], src="127.0.0.2")
        g2 = generation(s2, 2)
        w2 = write_regs(s2, 2, 40, UP_D00)
        wq = write_regs(s2, 2, 64, [2500, 7500])
        w1 = write_regs(s2, 1, 40, UP_D00)
        e2 = read_regs(s2, 2, 9, 1)
        check(w2 == ("exc", 2) and wq == "ok" and w1 == "ok" and generation(s2, 2) == g2 and e2 == (0,),
              "write_protect unit 2: upload refused (02) with its last_error left 0, query registers writable; "
              "unit 1 writable", "%r %r %r last_error %r" % (w2, wq, w1, e2))

        # Reload: the allow-list and read_only apply to live connections.
        s3 = connect(p[0], src="127.0.0.2")
        read_regs(s3, 1, 0, 2)
        d.write(acl_conf(args, p, v6, eng_allow="allow = 127.0.0.3\n", plc_ro="no"))
        d.hup()
        d.wait_log("configuration reloaded")
        time.sleep(0.2)
        gone = closed_by_peer(s3, 2.0)
        w = write_regs(s, 1, 40, UP_D00)
        check(gone and w == "ok" and not refused_at_once(p[0], src="127.0.0.3"),
              "SIGHUP: a live connection no longer allow-listed is closed, a read-only listener made writable "
              "accepts the live connection's write, the newly listed address is served", "%s %r" % (gone, w))
        for x in (s, s2, s3):
            x.close()
        check("running as root: set user = NAME" in d.logtext() if os.geteuid() == 0 else True,
              "started as root without user =: warning logged")
    finally:
        rc = d.stop()
        check(rc == 0, "daemon (acl) exits 0", "rc %s" % rc)

    # No warning when the privileges are dropped (user = nobody), as root
    # (or as root inside a user namespace when the test runs unprivileged).
    prefix = [] if os.geteuid() == 0 else ["unshare", "-r"]
    if prefix and subprocess.run(prefix + ["true"]).returncode != 0:
        print("conn: skip: root-warning check needs root or unprivileged user namespaces")
    else:
        port = free_port()
        d = Daemon(args.it2nd, args.tmp, "root")
        base = ("[daemon]\nstate_dir = %s/state_root\nsnapshot_interval = 3600\nfsync = no\n"
                "[modbus]\ntcp_listen = 127.0.0.1:%d\n" % (args.tmp, port))
        d.start(base, "ready", prefix=prefix)
        d.stop()
        warned = "running as root: set user = NAME" in d.logtext()
        ok_nobody = True
        if os.geteuid() == 0:
            d2 = Daemon(args.it2nd, args.tmp, "nobody")
            d2.start(base.replace("[modbus]", "user = nobody\n[modbus]"), "ready")
            d2.stop()
            ok_nobody = "running as root" not in d2.logtext() and "running as user nobody" in d2.logtext()
        check(warned and ok_nobody, "as root without user =: warning; with user = nobody: none")

    # Configuration errors name file:line.
    bad = [
        ("[listen:a]\naddress = 127.0.0.1:1\nallow = 10.0.0.1/8\n", "3: [listen:a] allow: '10.0.0.1/8': host bits set beyond /8"),
        ("[listen:a]\naddress = 127.0.0.1:1\nallow = 10.0.0.0/33\n", "3: [listen:a] allow: '10.0.0.0/33': prefix length must be 0..32"),
        ("[listen:a]\naddress = 127.0.0.1:1\nallow = plc.example\n", "3: [listen:a] allow: 'plc.example': not a numeric IPv4 or IPv6 address"),
        ("[listen:a]\nread_only = yes\n", "2: [listen:a] read_only: address is required in this section"),
        ("[listen:a]\naddress = 127.0.0.1:1\nallow =\n", "3: [listen:a] allow: expected IPv4/IPv6 addresses or prefixes"),
        ("[listen:a]\naddress = 127.0.0.1:1\nread_only = maybe\n", "3: [listen:a] read_only: expected yes or no"),
        ("[modbus]\ntcp_listen = 127.0.0.1:1\n[listen:b]\naddress = 127.0.0.1:1\n", "4: [listen:b] address: 127.0.0.1:1 is already a listener address"),
        ("[model:1]\nwrite_protect = 2\n", "2: [model:1] write_protect: expected yes or no"),
        ("[modbus]\nevict_idle = -1\n", "2: [modbus] evict_idle: expected milliseconds 0..86400000"),
        ("[modbus]\ntcp_keepalive = 9999\n", "2: [modbus] tcp_keepalive: expected seconds 0..7200 (0: off)"),
        ("[rtu:a]\ndevice = /dev/null\nt35_us = 10\n", "3: [rtu:a] t35_us: expected auto or microseconds 500..1000000"),
        ("[rtu:a]\ndevice = /dev/null\nread_only = 3\n", "3: [rtu:a] read_only: expected yes or no"),
    ]
    n = 0
    for text, want in bad:
        path = os.path.join(args.tmp, "bad.conf")
        with open(path, "w") as f:
            f.write(text)
        r = subprocess.run([args.it2nd, "-c", path, "--check-config"], capture_output=True, text=True)
        if r.returncode != 0 and (path + ":" + want) in r.stderr:
            n += 1
        else:
            fail("config error: want %r, got %r" % (want, r.stderr.strip()))
    check(n == len(bad), "%d bad access-control / slot / RTU keys refused with file:line" % n)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--out")
    ap.add_argument("--only", default="slots,emfile,rtu,acl")
    ap.add_argument("--quick", action="store_true", help="fewer rounds (make test)")
    args = ap.parse_args()
    args.tmp = tempfile.mkdtemp(prefix="it2nd-conn.")
    only = args.only.split(",")
    try:
        for name in ("slots", "emfile", "rtu", "acl"):
            if name in only:
                fn = globals().get("test_" + name)
                if fn:
                    fn(args)
    finally:
        if args.out and FIGS:
            old = {}
            try:
                with open(args.out) as f:
                    old = json.load(f)
            except (OSError, ValueError):
                pass
            old.update(FIGS)
            old["written_by"] = "tests/daemon/conn_test.py" + (" --quick" if args.quick else "")
            old["conditions"] = {"utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                                 "loadavg_1min": round(os.getloadavg()[0], 2), "cpus": os.cpu_count(),
                                 "note": "loopback TCP and ptys; lockout = connect to first reply of a "
                                         "new pymodbus client while max_clients (32) connections are held"}
            os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
            with open(args.out, "w") as f:
                json.dump(old, f, indent=2, sort_keys=True)
                f.write("\n")
        R.tidy(args.tmp)
    sys.exit(R.finish())


if __name__ == "__main__":
    main()
