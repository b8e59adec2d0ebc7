#!/usr/bin/python3
"""A disk filled by the WAL itself heals on its own (issue 20 item 4), with
the real it2nd on a small filesystem: a 4 MiB tmpfs mounted for the test
(root), or, where mount is not allowed, tests/daemon/failio.c's byte budget
(ENOSPC once the state directory's files would exceed it).

1. WAL fills the disk: the rest of the filesystem is taken by a file that
   stays (about 64 KiB left); one client writes until the WAL hits ENOSPC
   (exception 04), then goes on every 20 ms (up to 6 s, or 20 in a row acknowledged). Without any operator act a
   write must be acknowledged again within 5 s of the first refusal (the
   checkpoint runs on the reserve, the WAL shrinks), the last 20 writes
   all acknowledged. kill -9 and a restart: exactly the acknowledged state
   (T of the last acknowledged write, generation + the number acknowledged).
2. The same, killed (-9) as soon as the disk is full; the restart on the
   full disk accepts writes again within 5 s.
3. Disk filled by another process that takes every byte freed (the
   reserve used up, nothing left): every write refused for 2.5 s; the other
   file removed, writes acknowledged again within 5 s without a restart;
   kill -9 and restart: the acknowledged state.

Prints "skip suite: <reason>" and exits 0 when neither a mount nor the shim is
available.
usage: diskfull_test.py --it2nd PATH [--failio PATH] [--mode auto|tmpfs|shim]"""
import argparse, os, signal, socket, struct, subprocess, sys, tempfile, threading, time
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--it2nd", required=True)
ap.add_argument("--failio")
ap.add_argument("--mode", default="auto", choices=("auto", "tmpfs", "shim"))
ap.add_argument("--keep", action="store_true", help="keep the log and state (path printed)")
args = ap.parse_args()

R = report.Report("diskfull")
ok, fail = R.ok, R.fail
FAILS = R.fails

T = tempfile.mkdtemp(prefix="it2nd-diskfull.")
MNT = os.path.join(T, "mnt")
os.mkdir(MNT)
mode = None
if args.mode in ("auto", "tmpfs") and os.geteuid() == 0:
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m,mode=0755", "tmpfs", MNT],
                       capture_output=True, text=True)
    if r.returncode == 0:
        mode = "tmpfs"
    elif args.mode == "tmpfs":
        R.skip_suite("mount of a tmpfs refused: " + r.stderr.strip())
if mode is None and args.mode in ("auto", "shim"):
    if args.failio and os.path.exists(args.failio):
        mode = "shim"
    else:
        R.skip_suite("no tmpfs mount (not root or not allowed) and no failio.so for the byte budget")
if mode is None:
    R.skip_suite("no tmpfs mount (not root) and --mode tmpfs")

STATE = os.path.join(MNT, "state")
LOG = os.path.join(T, "daemon.log")
PORT = free_port()
CONF = os.path.join(T, "it2nd.conf")
with open(CONF, "w") as f:
    f.write("[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\n[modbus]\ntcp_listen = 127.0.0.1:%d\n"
            "[model:1]\nunit_id = 1\npreload = paper\n" % (STATE, PORT))
BUDGET_FILE = os.path.join(T, "budget")
proc = None

def dir_usage():
    """Bytes the state directory's files occupy (what the shim counts)."""
    n = 0
    for e in os.scandir(STATE):
        st = os.stat(e.path, follow_symlinks=False)
        n += max(st.st_blocks * 512, st.st_size)
    return n

def avail():
    if mode == "tmpfs":
        st = os.statvfs(MNT)
        return st.f_bavail * st.f_frsize
    return int(open(BUDGET_FILE).read()) - dir_usage()

def set_free(nbytes, name):
    """Take the filesystem's free space down to about nbytes with a file
    that stays (tmpfs), or set the budget so (shim)."""
    if mode == "tmpfs":
        take = avail() - nbytes
        with open(os.path.join(MNT, name), "ab", buffering=0) as f:
            chunk = b"\x55" * 65536
            while take > 0:
                try:
                    f.write(chunk[:min(take, len(chunk))])
                except OSError:
                    break
                take -= len(chunk)
    else:
        with open(BUDGET_FILE + ".tmp", "w") as f:
            f.write(str(dir_usage() + nbytes))
        os.rename(BUDGET_FILE + ".tmp", BUDGET_FILE)

hog_stop = threading.Event()
def hog():
    """Another process that takes every byte freed (so the checkpoint's
    freed WAL goes to it, not back to the reserve). It writes page after
    page while there is room: one page per 2 ms lost the race for the
    freed reserve to the checkpoint's re-made reserve whenever the daemon's
    timing shifted (io_uring: 2 failures in 3 runs), and the phase never
    reached "nothing left"."""
    with open(os.path.join(MNT, "filler2"), "ab", buffering=0) as f:
        while not hog_stop.is_set():
            if mode == "tmpfs":
                try:
                    f.write(b"\x55" * 4096)
                    continue  # room: the next page at once, as a process filling the disk would
                except OSError:
                    pass
            else:
                u = dir_usage()
                if int(open(BUDGET_FILE).read()) > u:
                    with open(BUDGET_FILE + ".tmp", "w") as b:
                        b.write(str(u))
                    os.rename(BUDGET_FILE + ".tmp", BUDGET_FILE)
            time.sleep(0.001)

def remove_filler(name):
    if mode == "tmpfs":
        os.unlink(os.path.join(MNT, name))
    else:
        with open(BUDGET_FILE + ".tmp", "w") as f:
            f.write(str(1 << 40))
        os.rename(BUDGET_FILE + ".tmp", BUDGET_FILE)

def start():
    global proc
    env = dict(os.environ)
    if mode == "shim":
        env.update(LD_PRELOAD=args.failio, IT2N_FAILIO_BUDGET=BUDGET_FILE, IT2N_FAILIO_BUDGET_DIR=STATE)
    proc = subprocess.Popen([args.it2nd, "-c", CONF, "-f", "-v"], stdout=open(LOG, "a"),
                            stderr=subprocess.STDOUT, env=env)
    for _ in range(200):
        try:
            c = Client(); c.close(); return
        except OSError:
            if proc.poll() is not None:
                break
            time.sleep(0.05)
    fail("daemon did not start: " + open(LOG).read()[-400:]); finish()

def kill9():
    global proc
    proc.send_signal(signal.SIGKILL); proc.wait(); proc = None

class Client:
    def __init__(self):
        self.s = socket.create_connection(("127.0.0.1", PORT), timeout=5)
        self.tid = 0
    def close(self): self.s.close()
    def recv(self, n):
        b = b""
        while len(b) < n:
            c = self.s.recv(n - len(b))
            if not c: raise OSError("closed")
            b += c
        return b
    def req(self, pdu):
        self.tid = (self.tid + 1) & 0xFFFF
        self.s.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, 1) + pdu)
        hdr = self.recv(8)
        body = self.recv(struct.unpack(">H", hdr[4:6])[0] - 2)
        return hdr[7], body
    def write(self, t):
        regs = [0, 0, 3, 65535, 63836, 0, 1700, 0, 0, t, 7000, 2000]  # D(0,0), T = t
        fc, body = self.req(struct.pack(">BHHB", 16, 40, len(regs), 2 * len(regs)) +
                            struct.pack(">%dH" % len(regs), *regs))
        return "exc %d" % body[0] if fc & 0x80 else "ok"
    def read(self, addr, n):
        fc, body = self.req(struct.pack(">BHH", 3, addr, n))
        if fc & 0x80: raise OSError("exception %d" % body[0])
        return list(struct.unpack(">%dH" % n, body[1:1 + 2 * n]))

def gen(c):
    hi, lo = c.read(7, 2); return hi * 65536 + lo

value = 1000
def next_value():
    global value
    value = value % 9000 + 1
    return value

def write_phase(name, until, after_s, free_when_stuck=False):
    """Write as fast as acknowledged until the first refusal (at most 60 s),
    then (until == "after") go on every 20 ms for after_s s. With
    free_when_stuck, first go on writing until every write has been
    refused for 2.5 s (stuck: the reserve is used up too; at most 40 s),
    then remove the other file and go on for after_s s. Returns (results
    [(t, value, result)], t of the first refusal or None, t when the file
    was removed or None)."""
    c = Client()
    res, t_refused, t_freed, t0 = [], None, None, time.time()
    last_ok_t = t0
    while True:
        v = next_value()
        r = c.write(v)
        now = time.time()
        res.append((now, v, r))
        if r == "ok":
            last_ok_t = now
        elif t_refused is None:
            t_refused = now
            if until == "refused": break
        if t_refused is None and now - t0 > 60:
            break
        if t_refused is None:
            continue
        if free_when_stuck and t_freed is None:
            if now - last_ok_t >= 2.5 or now - t_refused > 40:
                hog_stop.set(); hog_thread.join()
                remove_filler("filler2")
                t_freed = time.time()
            else:
                time.sleep(0.005)
            continue
        ref = t_freed or t_refused
        if now - ref > after_s: break
        if len(res) >= 20 and all(r == "ok" and t > ref for t, _, r in res[-20:]):
            break  # healed: 20 in a row acknowledged
        time.sleep(0.02)
    c.close()
    return res, t_refused, t_freed

def check_heal(name, res, t_from, what):
    others = [r for _, _, r in res if r not in ("ok", "exc 4")]
    if others: fail("%s: answers other than ok and exception 04: %s" % (name, others[:3]))
    healed = [t for t, _, r in res if r == "ok" and t > t_from]
    if not healed:
        fail("%s: no write acknowledged after %s (%d refused)" % (name, what, sum(r != "ok" for _, _, r in res)))
        return None
    dt = healed[0] - t_from
    tail = [r for _, _, r in res[-20:]]
    if dt > 5.0: fail("%s: first write acknowledged %.2f s after %s (> 5 s)" % (name, dt, what))
    if tail.count("ok") != 20: fail("%s: the last 20 writes not all acknowledged: %s" % (name, tail))
    return dt

acked = 0        # writes acknowledged since g0
last_ok = None
def account(res):
    global acked, last_ok
    for _, v, r in res:
        if r == "ok":
            acked += 1; last_ok = v

def check_restart(name):
    start()
    c = Client()
    g, t = gen(c), c.read(1024, 1)[0]
    c.close()
    if g == g0 + acked and t == last_ok:
        ok("%s: kill -9 + restart: exactly the acknowledged state (%d writes acknowledged in all, T %d)"
           % (name, acked, t))
    else:
        fail("%s: after kill -9 + restart: generation %d (want %d), T %d (want %d)" % (name, g, g0 + acked, t, last_ok))

def log_has(s, since):
    return s in open(LOG).read()[since:]

def finish():
    if proc is not None: kill9()
    hog_stop.set()
    if mode == "tmpfs": subprocess.run(["umount", "-l", MNT])
    if args.keep and not FAILS: print("diskfull: kept " + T)
    else: R.tidy(T, LOG)
    print("diskfull: %s" % mode)
    sys.exit(R.finish())

def on_term(signum, frame):
    fail("stopped by signal %d (timeout?)" % signum)
    finish()
signal.signal(signal.SIGTERM, on_term)  # `timeout` must not leave the tmpfs mounted

try:
    if mode == "shim":
        with open(BUDGET_FILE, "w") as f: f.write(str(1 << 40))
    start()
    c = Client(); g0 = gen(c); c.close()
    rs = os.path.join(STATE, "reserve")
    if os.path.exists(rs) and os.stat(rs).st_blocks * 512 >= 256 << 10:
        ok("checkpoint reserve in place (%d KiB allocated)" % (os.stat(rs).st_blocks // 2))
    else:
        fail("no checkpoint reserve in %s: %s" % (STATE, os.listdir(STATE)))

    # 1. The WAL fills the disk; nothing is freed.
    set_free(64 << 10, "filler")
    since = len(open(LOG).read())
    res, t_ref, _ = write_phase("wal-full", "after", 6.0)
    account(res)
    wal_kib = None
    if t_ref is None:
        fail("wal-full: the disk never filled (%d writes)" % len(res))
    else:
        n_before = sum(1 for t, _, r in res if t < t_ref and r == "ok")
        dt = check_heal("wal-full", res, t_ref, "the first refusal")
        if dt is not None and log_has("checkpoint reserve", since) and log_has("writes accepted again", since):
            ok("WAL filled the disk after %d writes; no operator act: writes acknowledged again %.2f s after the "
               "first refusal (reserve released for the checkpoint, logged), last 20 all acknowledged"
               % (n_before, dt))
        elif dt is not None:
            fail("wal-full: healed but the log does not say how: " + open(LOG).read()[since:][-600:])
    kill9()
    check_restart("wal-full")

    # 2. Full again, killed at once; the restart on the full disk heals.
    res, t_ref, _ = write_phase("restart-full", "refused", 0)
    account(res)
    kill9()
    if t_ref is None:
        fail("restart-full: the disk never filled")
    t_start = time.time()
    start()
    res2, _, _ = write_phase("restart-full", "after", 6.0)
    # write_phase stops at the first refusal + 7 s; if none is refused the
    # restart healed before the first write was tried.
    account(res2)
    dt = check_heal("restart-full", [(t_start, 0, "exc 4")] + res2, t_start, "the restart")
    if dt is not None:
        ok("killed with the disk full, restarted on the full disk: writes acknowledged %.2f s after the start" % dt)
    kill9()
    check_restart("restart-full")

    # 3. Filled by someone else, who takes every byte freed: refused once
    #    the reserve is used up, until the operator frees space.
    since = len(open(LOG).read())
    set_free(0, "filler2")
    hog_thread = threading.Thread(target=hog)
    hog_thread.start()
    res, t_ref, t_freed = write_phase("other-full", "after", 6.0, free_when_stuck=True)
    account(res)
    if t_ref is None or t_freed is None:
        fail("other-full: the disk never filled")
    else:
        stuck = t_freed - max([t for t, _, r in res if r == "ok" and t < t_freed] or [t_ref])
        refused = sum(1 for t, _, r in res if r != "ok")
        dt = check_heal("other-full", res, t_freed, "space was freed")
        if stuck < 2.4:
            fail("other-full: writes were not refused for 2.5 s before the file was removed (%.2f s)" % stuck)
        elif not (log_has("no room for the checkpoint reserve", since) or log_has("snapshot failed", since)):
            fail("other-full: the reserve was never used up (no 'no room for the checkpoint reserve' or "
                 "'snapshot failed' line)")
        elif dt is not None:
            ok("disk filled by another file: the reserve used up, every write refused for %.1f s (%d refused in "
               "all), then acknowledged %.2f s after the file was removed, no restart" % (stuck, refused, dt))
    kill9()
    check_restart("other-full")
except Exception as e:  # a broken connection etc.: a failure, with the log
    fail("exception: %r" % (e,))
finish()
