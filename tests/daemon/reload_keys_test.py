#!/usr/bin/python3
"""reload_keys_test.py -- what a reload (SIGHUP) does with each kind of key,
as docs/daemon.md ("Reload (SIGHUP)", the keys' "reload" column) and
docs/sparkplug.md promise, against the real it2nd on loopback TCP.

  reload_keys_test.py --it2nd BIN --plc PLC

* keys a reload applies ("yes"): fsync (no -> yes: the next acknowledged
  write is fsynced, counted by /metrics; yes -> no: no longer),
  snapshot_interval (3600 -> 1: a snapshot within seconds of a write);
* keys that need a restart ("restart"): state_dir and user changed: each
  logged, the running values kept (the WAL grows in the old directory, the
  new one is not created, the process keeps its uid);
* a bad file that also removes a model holding data (removed = yes), adds
  one, moves a unit, changes the word order and fsync: refused as a whole
  (a bad value, max_models below the sections, an unknown key), every
  model and option as before; the same file without the error applies all
  of it (so the checks above can see a change);
* [sparkplug] (mosquitto and paho needed, else that part is skipped):
  edge_node_id changed together with a model added: logged as taking
  effect at restart, the new birth sequence still under the old edge node
  id, nothing under the new one until a restart; a [sparkplug] section
  added to a daemon started without one: logged, nothing connects.

reload_test.py tests the all-or-nothing rule on damaged files and the
removal rule; this script the decisions per key.
"""
import importlib.util
import os
import queue
import re
import subprocess
import sys
import tempfile
import time
import urllib.request

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import daemon as it2nd_proc  # noqa: E402
from it2ntest.daemon import file_sig  # noqa: E402
from it2ntest import report  # noqa: E402
from it2ntest.broker import MOSQUITTO, Broker  # noqa: E402
from it2ntest.modbus import connect, read_regs, write_regs  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

R = report.Report("reload-keys")
check = R.check
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PAPER = os.path.join(ROOT, "examples", "paper_4x4.csv")
# One point of model 6 (2x2): upload registers i j fp(D) x y z T I F.
UP_6 = ["40", "0", "0", "3", "65535", "63836", "0", "1700", "0", "0", "4500", "7000", "2000"]
RELOADED = "configuration reloaded"
REFUSED = "reload failed; keeping the running configuration"


def conf(state, port, mport, daemon="", modbus="", models=None, extra=""):
    """Models 1 (paper), 5 (3x3, data uploaded by the test) and 6 (2x2)
    unless models says otherwise."""
    if models is None:
        models = ("[model:1]\nunit_id = 1\npreload = paper\n[model:5]\nunit_id = 5\nn = 3\nm = 3\n"
                  "[model:6]\nunit_id = 6\nn = 2\nm = 2\n")
    return ("[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\nfsync = no\n%s"
            "[modbus]\ntcp_listen = 127.0.0.1:%d\n%s[metrics]\nlisten = 127.0.0.1:%d\n%s%s"
            % (state, daemon, port, modbus, mport, models, extra))


class Daemon(it2nd_proc.Daemon):
    def reload(self, text, want, timeout=5.0):
        """The file written (atomically), SIGHUP: the log lines up to want,
        or None."""
        self.write_conf(text, atomic=True)
        return self.hup_and_wait(want, timeout)


def plc(args, *cmd, unit=1):
    p = subprocess.run([args.plc, "--tcp", "127.0.0.1:%d" % args.port, "--unit", str(unit)] + list(cmd),
                       capture_output=True, text=True, timeout=60)
    return p.returncode, (p.stdout + p.stderr).strip()


def fsyncs(mport):
    """it2nd_wal_fsync_duration_seconds_count from /metrics."""
    with urllib.request.urlopen("http://127.0.0.1:%d/metrics" % mport, timeout=5) as r:
        text = r.read().decode()
    m = re.search(r"^it2nd_wal_fsync_duration_seconds_count (\d+)", text, re.M)
    return int(m.group(1)) if m else None


def status(port, unit, reg, n=1):
    """Status block registers (FC 04) on a fresh connection: a tuple, or
    ("exc", code)."""
    s = connect(port)
    try:
        return read_regs(s, unit, reg, n)
    finally:
        s.close()


def write6(args):
    rc, out = plc(args, "write", *UP_6, unit=6)
    return out == "ok"


# ---- [daemon] keys ----------------------------------------------------------

def daemon_keys(args, d, state, base):
    # fsync no -> yes -> no: counted by the WAL fsync histogram.
    f0 = fsyncs(args.mport)
    ok6 = write6(args)
    check(ok6 and fsyncs(args.mport) == f0, "fsync = no at start: an acknowledged write is not fsynced",
          "write %s, fsyncs %s -> %s" % (ok6, f0, fsyncs(args.mport)))
    new = d.reload(base.replace("fsync = no\n", "fsync = yes\n"), RELOADED)
    f1 = fsyncs(args.mport)
    ok6 = write6(args)
    f2 = fsyncs(args.mport)
    check(new is not None and ok6 and f2 is not None and f1 is not None and f2 > f1,
          "SIGHUP to fsync = yes: the next acknowledged write is fsynced (%s -> %s)" % (f1, f2),
          "reload %s, write %s" % (new is not None, ok6))
    new = d.reload(base, RELOADED)
    f3 = fsyncs(args.mport)
    ok6 = write6(args)
    check(new is not None and ok6 and fsyncs(args.mport) == f3,
          "SIGHUP back to fsync = no: writes no longer fsynced", "%s -> %s" % (f3, fsyncs(args.mport)))

    # snapshot_interval 3600 -> 1: a snapshot follows a write within seconds.
    snap = os.path.join(state, "snapshot")
    s0 = file_sig(snap)
    new = d.reload(base.replace("snapshot_interval = 3600\n", "snapshot_interval = 1\n"), RELOADED)
    ok6 = write6(args)
    end = time.monotonic() + 5
    while file_sig(snap) == s0 and time.monotonic() < end:
        time.sleep(0.05)
    check(new is not None and ok6 and file_sig(snap) != s0, "SIGHUP to snapshot_interval = 1: a snapshot follows a write",
          "reload %s, write %s, snapshot %s -> %s" % (new is not None, ok6, s0, file_sig(snap)))
    d.reload(base, RELOADED)

    # state_dir and user: restart keys, logged, the running values kept.
    other = state + "-new"
    text = base.replace("state_dir = %s\n" % state, "state_dir = %s\nuser = nobody\n" % other)
    wal0 = file_sig(os.path.join(state, "wal"))
    uid0 = proc_uid(d.proc.pid)
    new = d.reload(text, RELOADED)
    ok6 = write6(args)
    wal1 = file_sig(os.path.join(state, "wal"))
    check(new is not None and "reload: state_dir change (%s -> %s) takes effect at restart" % (state, other) in new
          and "reload: user change takes effect at restart" in new,
          "SIGHUP with another state_dir and user: both logged as taking effect at restart", new)
    check(ok6 and wal1 is not None and wal1 != wal0 and not os.path.exists(other) and proc_uid(d.proc.pid) == uid0,
          "... the WAL still written in the old state_dir, the new one not created, uid %s kept" % uid0,
          "write %s, wal %s -> %s, %s exists %s, uid %s" % (ok6, wal0, wal1, other, os.path.exists(other),
                                                          proc_uid(d.proc.pid)))
    d.reload(base, RELOADED)


def proc_uid(pid):
    with open("/proc/%d/status" % pid) as f:
        return next(line.split()[1] for line in f if line.startswith("Uid:"))


# ---- [model:] sections and the listener ---------------------------------------

def models_and_listener(args, d, state, base):
    m8 = "[model:8]\nunit_id = 8\nn = 2\nm = 2\n"
    # A model a PLC reconfigured keeps its data while its section stays.
    s = connect(args.port)
    try:
        wr = write_regs(s, 6, 32, [3, 3, 0])
    finally:
        s.close()
    rc, out = plc(args, "upload", PAPER, unit=6)
    new = d.reload(base + m8, RELOADED)
    rc2, out2 = plc(args, "verify", PAPER, "3", unit=6)
    check(wr == "ok" and rc == 0 and new is not None and "model 8 added" in new and rc2 == 0
          and status(args.port, 8, 1, 2) == (0, 2),
          "model 6 reconfigured 3x3 by the PLC, paper uploaded; SIGHUP adding model 8 (section 6 unchanged): "
          "model 6 keeps its data, model 8 served empty",
          "cfg write %r, upload %d %s, reload %s, verify %d %s, unit 8 %r"
          % (wr, rc, out[-200:], new, rc2, out2[-200:], status(args.port, 8, 1, 2)))

    # Unit ids swapped: each model answers on the other's unit at once.
    swapped = (base.replace("[model:5]\nunit_id = 5\n", "[model:5]\nunit_id = 8\n")
               + m8.replace("unit_id = 8", "unit_id = 5"))
    new = d.reload(swapped, RELOADED)
    rc, out = plc(args, "verify", PAPER, "3", unit=8)
    check(new is not None and "model 5 moves from unit 5 to unit 8" in new and "model 8 moves from unit 8 to unit 5"
          in new and rc == 0 and status(args.port, 5, 1, 2) == (0, 2),
          "SIGHUP swapping the units of models 5 and 8: unit 8 serves model 5's data, unit 5 the empty 2x2 model 8",
          "%s; verify unit 8: %d %s; unit 5 %r" % (new, rc, out[-200:], status(args.port, 5, 1, 2)))

    # kind changed: the model is replaced, its points cleared (the kind key
    # written, as a model holding data needs).
    kind = swapped.replace("[model:6]\nunit_id = 6\nn = 2\nm = 2\n",
                           "[model:6]\nunit_id = 6\nkind = bspline\nn = 3\nm = 3\n")
    new = d.reload(kind, RELOADED)
    st = status(args.port, 6, 1, 5)
    check(new is not None and "reload: model 6 replaced by a bspline model of 3x3" in new
          and "points cleared" in new and st[0] == 0 and st[4] == 0,
          "SIGHUP with model 6's kind = bspline: replaced (logged), its points cleared", "%s; unit 6 %r" % (new, st))

    # The listener moved: the new address accepts, the old one no longer,
    # a connection made before the reload is served on.
    live = connect(args.port)
    other = free_port()
    moved = kind.replace("tcp_listen = 127.0.0.1:%d\n" % args.port, "tcp_listen = 127.0.0.1:%d\n" % other)
    try:
        new = d.reload(moved, RELOADED)
        r_live = read_regs(live, 8, 1, 1)
        r_new = status(other, 8, 1)
        try:
            status(args.port, 8, 1)
            old_closed = False
        except OSError:
            old_closed = True
        check(new is not None and r_live == (2,) and r_new == (2,) and old_closed,
              "SIGHUP moving tcp_listen: served on the new port, the old one closed, a live connection kept",
              "%s; live %r, new %r, old closed %s" % (new, r_live, r_new, old_closed))
        new = d.reload(base, RELOADED)  # back as the parts after this expect
        check(new is not None and read_regs(live, 1, 1, 1) == (2,) and status(args.port, 1, 1) == (2,),
              "SIGHUP back to the first file: the old port served again, the live connection still kept", new)
    finally:
        live.close()


# ---- [rtu:] and [link:] sections -----------------------------------------------

def serial_sections(args, d, base):
    """Reopened only if their sections changed: not when only their lines
    moved (a comment or a section added above them)."""
    ptys = [os.openpty() for _ in range(2)]
    try:
        serial = ("[rtu:bus]\ndevice = %s\nbaud = 19200\n[link:inst]\ntype = serial\ndevice = %s\nbaud = 115200\n"
                  % (os.ttyname(ptys[0][1]), os.ttyname(ptys[1][1])))
        new = d.reload(base + serial, RELOADED)
        check(new is not None and "rtu: ports changed; reopening" in new and "links changed; reopening" in new,
              "SIGHUP adding [rtu:bus] and [link:inst]: both opened", new)
        new = d.reload("# a comment moves every line below it\n" + base + serial, RELOADED)
        check(new is not None and "reopening" not in new,
              "SIGHUP with the same sections on other lines (a comment above): neither reopened", new)
        new = d.reload(base + serial.replace("19200", "38400").replace("115200", "57600"), RELOADED)
        check(new is not None and "rtu: ports changed; reopening" in new and "links changed; reopening" in new,
              "SIGHUP with another baud in each: both reopened", new)
        d.reload(base, RELOADED)
    finally:
        for m, s in ptys:
            os.close(m)
            os.close(s)


# ---- all or nothing ---------------------------------------------------------

def all_or_nothing(args, d, state, base):
    """A file with many valid changes and one error: nothing applied."""
    models = ("[model:1]\nunit_id = 11\npreload = paper\n[model:5]\nremoved = yes\n"
              "[model:6]\nunit_id = 6\nn = 2\nm = 2\n[model:7]\nunit_id = 7\npreload = paper\n")
    changed = conf(state, args.port, args.mport, modbus="float_word_order = CDAB\n", models=models)
    changed = changed.replace("fsync = no\n", "fsync = yes\n")
    errors = {
        "a bad value ([modbus] int32_word_order = XYZW)": (
            changed.replace("float_word_order = CDAB\n", "float_word_order = CDAB\nint32_word_order = XYZW\n"),
            "int32_word_order"),
        "max_models below the sections": (changed.replace("fsync = yes\n", "fsync = yes\nmax_models = 2\n"),
                                          "max_models"),
        "an unknown key in the last section": (changed + "bogus = 1\n", "bogus"),
    }
    for name, (text, want) in errors.items():
        before = (status(args.port, 1, 21), status(args.port, 5, 0, 10), status(args.port, 6, 0, 10))
        f0 = fsyncs(args.mport)
        new = d.reload(text, REFUSED)
        why = []
        if new is None:
            why.append("no '%s' line: %s" % (REFUSED, d.text()[-600:]))
        elif want not in new or RELOADED in new or "removed" in new:
            why.append("log: %s" % new)
        rc, out = plc(args, "verify", PAPER, "3", unit=5)
        if rc != 0:
            why.append("model 5's data not served: %s" % out[-300:])
        now = (status(args.port, 1, 21), status(args.port, 5, 0, 10), status(args.port, 6, 0, 10))
        if now != before:
            why.append("status (word order, models 5, 6) %r, was %r" % (now, before))
        for unit in (7, 11):
            if status(args.port, unit, 0) != ("exc", 0x0B):
                why.append("unit %d answers %r" % (unit, status(args.port, unit, 0)))
        ok6 = write6(args)
        if not ok6 or fsyncs(args.mport) != f0:
            why.append("write %s, fsyncs %s -> %s (fsync = yes applied)" % (ok6, f0, fsyncs(args.mport)))
        check(not why, "SIGHUP with %s and valid changes (model 5 removed = yes, 7 added, 1 on unit 11, CDAB, "
              "fsync): refused, every model and option kept" % name, "; ".join(why))
    new = d.reload(changed, RELOADED)
    check(new is not None and status(args.port, 5, 0) == ("exc", 0x0B) and status(args.port, 7, 1) == (2,)
          and status(args.port, 11, 1) == (2,) and status(args.port, 11, 21) == (1,)
          and status(args.port, 1, 0) == ("exc", 0x0B),
          "the same file without the error: all of it applied (5 gone, 7 served, model 1 on unit 11, CDAB)",
          "%s; units 5 %r, 7 %r, 11 %r" % (new, status(args.port, 5, 0), status(args.port, 7, 1),
                                          status(args.port, 11, 1)))


# ---- [sparkplug] ---------------------------------------------------------------

class Host:
    """Every topic published under spBv1.0/, in arrival order."""

    def __init__(self, port):
        import paho.mqtt.client as mqtt
        self.q, self.sub = queue.Queue(), queue.Queue()
        self.c = mqtt.Client(client_id="reload-keys-%d" % os.getpid(), clean_session=True, protocol=mqtt.MQTTv311)
        self.c.on_message = lambda c, u, m: self.q.put(m.topic)
        self.c.on_subscribe = lambda c, u, mid, qos: self.sub.put(mid)
        self.c.connect("127.0.0.1", port, keepalive=30)
        self.c.loop_start()
        self.c.subscribe("spBv1.0/#", qos=1)
        self.sub.get(timeout=5)

    def topics(self, timeout, until=None):
        """Topics arriving within timeout (until one ends with until)."""
        got, end = [], time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                t = self.q.get(timeout=max(0.0, end - time.monotonic()))
            except queue.Empty:
                break
            got.append(t)
            if until and t.endswith(until):
                break
        return got

    def close(self):
        self.c.loop_stop()
        self.c.disconnect()


def sparkplug(args, tmp, d, base):
    if importlib.util.find_spec("paho") is None:
        R.skip("[sparkplug] on reload: no paho-mqtt (python3-paho-mqtt)")
        return
    if not MOSQUITTO:
        R.skip("[sparkplug] on reload: no mosquitto")
        return
    bport = free_port()
    broker = Broker(tmp, bport, "listener %d 127.0.0.1\nallow_anonymous true\n" % bport)
    broker.start()
    host = Host(bport)
    node = None
    try:
        # The daemon started without [sparkplug]: adding one needs a restart.
        spb = "[sparkplug]\nbroker = 127.0.0.1:%d\ngroup_id = g\nedge_node_id = e1\n" % bport
        new = d.reload(base + spb, RELOADED)
        seen = host.topics(1.0)
        check(new is not None and "reload: [sparkplug] added; takes effect at restart" in new and not seen,
              "SIGHUP adding [sparkplug]: logged as taking effect at restart, nothing published",
              "%s; published %s" % (new, seen))
        d.reload(base, RELOADED)

        port, mport = free_port(), free_port()
        state = os.path.join(tmp, "spb-state")
        one = "[model:1]\nunit_id = 1\npreload = paper\n"
        text = conf(state, port, mport, models=one, extra=spb)
        node = Daemon(args.it2nd, os.path.join(tmp, "spb.conf"), os.path.join(tmp, "spb.log"), port=port)
        node.write_conf(text)
        node.start()
        seen = host.topics(5.0, until="DBIRTH/e1/model-1")
        check("spBv1.0/g/NBIRTH/e1" in seen, "node e1 born", seen)
        new = node.reload("# a comment moves every line below it\n" + text, RELOADED)
        check(new is not None and "[sparkplug]" not in new,
              "SIGHUP with the same [sparkplug] on other lines: no change logged", new)
        two = one + "[model:2]\nunit_id = 2\npreload = paper\n"
        new = node.reload(conf(state, port, mport, models=two, extra=spb.replace("e1", "e2")), RELOADED)
        seen = host.topics(5.0, until="DBIRTH/e1/model-2")
        check(new is not None and "reload: [sparkplug] changes take effect at restart" in new,
              "SIGHUP with edge_node_id e1 -> e2 and model 2 added: the [sparkplug] change logged for the restart",
              new)
        check("spBv1.0/g/NBIRTH/e1" in seen and "spBv1.0/g/DBIRTH/e1/model-2" in seen
              and not any("/e2" in t for t in seen),
              "... the new birth sequence (model 2) published as e1, nothing as e2", seen)
        node.stop()
        node.start()
        seen = host.topics(5.0, until="DBIRTH/e2/model-2")
        check("spBv1.0/g/NBIRTH/e2" in seen and "spBv1.0/g/DBIRTH/e2/model-2" in seen,
              "restart: born as e2 with models 1 and 2", seen)
    finally:
        if node is not None:
            rc = node.stop()
            check(rc == 0, "Sparkplug node: SIGTERM exits 0", "%s: %s" % (rc, node.text()[-1500:]))
        host.close()
        broker.stop()


def main():
    args = it2nd_proc.arg_parser("it2nd", "plc").parse_args()
    tmp = tempfile.mkdtemp(prefix="it2nd-reload-keys.")
    args.port, args.mport = free_port(), free_port()
    state = os.path.join(tmp, "state")
    base = conf(state, args.port, args.mport)
    d = Daemon(args.it2nd, os.path.join(tmp, "it2nd.conf"), os.path.join(tmp, "it2nd.log"), port=args.port,
               cwd=tmp)
    d.write_conf(base)
    try:
        d.start()
        rc, out = plc(args, "upload", PAPER, unit=5)
        check(rc == 0, "the paper data set uploaded to model 5", out)
        daemon_keys(args, d, state, base)
        sparkplug(args, tmp, d, base)
        models_and_listener(args, d, state, base)
        serial_sections(args, d, base)
        all_or_nothing(args, d, state, base)  # last: it changes the models
    except (OSError, ConnectionError, RuntimeError, subprocess.TimeoutExpired, queue.Empty) as e:
        import traceback
        traceback.print_exc()
        R.fail("aborted: %r" % e)
    finally:
        rc = d.stop()
        check(rc == 0, "SIGTERM exits 0 (under ASan: no error, no leak)", "%s: %s" % (rc, d.text()[-1500:]))
    R.tidy(tmp)
    sys.exit(R.finish())


if __name__ == "__main__":
    main()
