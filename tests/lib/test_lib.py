#!/usr/bin/python3
"""Self-test of the shared test helpers (tests/lib): a failing check makes the
exit status non-zero, a script that checked nothing does not pass, skips are
said in the runner's words and never as ok, free ports are below the
ephemeral range and never handed out twice, Daemon starts, waits for its
listener, stops, kills -9 and keeps its log, Broker runs mosquitto, the raw Modbus TCP helpers decode replies and
exceptions and refuse a mismatched reply, and
testlib.sh does the same for shell scripts (TL_FAIL_FAST: the first failure
exits 1)."""
import os
import re
import socket
import subprocess
import sys
import struct
import tempfile
import threading

LIB = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, LIB)
from it2ntest import broker, daemon, modbus, ports, proc, report  # noqa: E402

R = report.Report("lib-unit")
T = tempfile.mkdtemp(prefix="it2n-tlib.")
PY = "/usr/bin/python3"

# The runner's patterns (tests/run_suites.py).
PART_SKIP = re.compile(r"^[^ \n].*?: skip: (.*)$", re.M)
SUITE_SKIP = re.compile(r"^skip suite: (.*)$", re.M)


def child(body):
    """Run body as a script using it2ntest: (exit status, stdout, stderr)."""
    path = os.path.join(T, "child.py")
    with open(path, "w") as f:
        f.write("import sys\nsys.path.insert(0, %r)\nfrom it2ntest import report\n%s" % (LIB, body))
    return proc.run([PY, path], timeout=30)


# ---- report
rc, out, err = child('R = report.Report("c")\nR.check(True, "a")\nR.check(1 == 2, "b", "1 != 2")\n'
                     'R.check(True, "c")\nsys.exit(R.finish())\n')
R.check(rc == 1, "one failing check among passing ones: exit status 1", "got %d" % rc)
R.check("c: FAIL: b: 1 != 2" in err and "c: ok: a" in out and "c: ok: c" in out,
        "ok lines on stdout, the FAIL line with its detail on stderr", out + err)
rc, out, err = child('R = report.Report("c")\nR.check(True, "a")\nsys.exit(R.finish())\n')
R.check(rc == 0 and "c: ok: a" in out and "FAIL" not in out + err, "only passing checks: exit status 0",
        "%d %s %s" % (rc, out, err))
rc, out, err = child('R = report.Report("c")\nsys.exit(R.finish())\n')
R.check(rc == 1 and "no check ran" in err, "no check ran and nothing skipped: exit status 1", "got %d" % rc)
rc, out, err = child('R = report.Report("c")\nR.skip("no mosquitto")\nsys.exit(R.finish())\n')
R.check(rc == 0 and PART_SKIP.findall(out) == ["no mosquitto"] and " ok" not in out,
        "a skipped part is printed with the word skip and its reason (what the runner counts), not as ok", out)
rc, out, err = child('R = report.Report("c")\nR.skip_suite("not root")\nprint("after")\n')
R.check(rc == 0 and SUITE_SKIP.findall(out) == ["not root"] and "after" not in out,
        "skip_suite: 'skip suite: reason', exit 0, nothing after it", out)
rc, out, err = child('R = report.Report("c", quiet_ok=True)\nR.check(True, "a")\nR.check(False, "b")\n'
                     'sys.exit(R.finish())\n')
R.check(rc == 1 and "c: ok: a" not in out and "c: FAIL: b" in err, "quiet_ok: failures still said and counted",
        out + err)
rc, out, err = child('sys.exit(report.Report("c").verdict(["x is wrong", "y is wrong"], "all fine"))\n')
R.check(rc == 1 and "c: FAIL: x is wrong" in err and "c: FAIL: y is wrong" in err and "all fine" not in out,
        "verdict: each problem a FAIL, exit 1", "%d %s %s" % (rc, out, err))
rc, out, err = child('sys.exit(report.Report("c").verdict([], "all fine"))\n')
R.check(rc == 0 and out == "c: ok: all fine\n", "verdict: no problem: the summary as one ok line, exit 0",
        "%d %r %s" % (rc, out, err))
for cond, want in (("True", "removed"), ("False", "kept")):
    d = tempfile.mkdtemp(dir=T)
    with open(os.path.join(d, "x.log"), "w") as f:
        f.write("early\n" + "late line\n")
    rc, out, err = child('R = report.Report("c", quiet_ok=True)\nR.check(%s, "a")\nR.tidy(%r, %r, tail=10)\n'
                         % (cond, d, os.path.join(d, "x.log")))
    R.check(os.path.isdir(d) == (want == "kept") and (("late line" in err and "early" not in err
                                                         and "c: logs kept in " + d in err) == (want == "kept")),
            "tidy: temp dir %s %s" % (want, "(the log's tail shown)" if want == "kept" else "when all passed"), err)

# ---- ports
lo = ports.ephemeral_low()
got = [ports.free_port() for _ in range(200)]
R.check(len(set(got)) == len(got), "free_port: 200 calls, no port twice")
R.check(all(1024 <= p < lo for p in got), "free_port: below the ephemeral range (%d)" % lo)
s = socket.socket()
s.bind(("127.0.0.1", got[-1]))
s.close()
R.check(True, "free_port: the port can be bound")
try:
    ports.free_port(avoid=set(range(1024, lo)))
    R.fail("free_port with every port avoided: no error")
except RuntimeError:
    R.ok("free_port with every port avoided: RuntimeError, not a used port")

# ---- proc
rc, out, err = proc.run(["sh", "-c", "echo a; echo b >&2; exit 3"])
R.check((rc, out, err) == (3, "a\n", "b\n"), "run: status, stdout and stderr", (rc, out, err))
try:
    proc.run(["sleep", "5"], timeout=0.2)
    R.fail("run: a hang past the timeout went unnoticed")
except subprocess.TimeoutExpired:
    R.ok("run: a hang past the timeout raises TimeoutExpired")

# ---- daemon: a stand-in for it2nd that reads tcp_listen from -c CONF
fake = os.path.join(T, "fake-it2nd")
with open(fake, "w") as f:
    f.write("#!%s\nimport socket, sys, time\nconf = open(sys.argv[sys.argv.index('-c') + 1]).read()\n"
            "port = int(conf.split('tcp_listen = 127.0.0.1:')[1].split()[0])\n"
            "if 'die' in conf: print('bad config', flush=True); sys.exit(1)\n"
            "time.sleep(0.3)\ns = socket.socket()\ns.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)\ns.bind(('127.0.0.1', port))\n"
            "import signal\nsignal.signal(signal.SIGHUP, lambda *a: print('reloaded', flush=True))\n"
            # the line goes out before listen(): start() returns once a connect succeeds,
            # and the checks below read the log then (printed after listen() it raced them)
            "print('listening', port, flush=True)\ns.listen()\nwhile True: s.accept()[0].close()\n" % PY)
os.chmod(fake, 0o755)
d = daemon.start_simple(fake, T, "d1")
R.check(proc.wait_port(d.port, timeout=1), "Daemon: start returns once it listens")
R.check("listening %d" % d.port in d.text(), "Daemon: its output is in the log", d.text())
rc = d.stop()
R.check(rc == -15 and not d.alive(), "Daemon: stop sends SIGTERM and waits", rc)
d.start()
R.check(d.kill9() == -9, "Daemon: kill9 is SIGKILL")
R.check(d.text().count("listening") == 2, "Daemon: the log is appended to across restarts", d.text())
d.start(ready="listening %d" % d.port, timeout=5)
R.check(d.text().count("listening") == 3, "Daemon: start(ready=) waits for the text written by this start",
        d.text())
d.hup()
R.check(d.wait_log("reloaded", timeout=3) and not d.wait_log("reloaded", timeout=0.1, since=len(d.text())),
        "Daemon: hup and wait_log (since: only what came after)")
new = d.hup_and_wait("reloaded", timeout=3)
R.check(new is not None and new.count("reloaded") == 1, "Daemon: hup_and_wait: the log after this SIGHUP", new)
R.check(d.hup_and_wait("never logged", timeout=0.2) is None, "Daemon: hup_and_wait: None when the text does not come")
d.stop()
try:
    daemon.start_simple(fake, T, "d2", body="die = yes\n")
    R.fail("Daemon: one that exits at start was taken as started")
except RuntimeError as e:
    R.check("bad config" in str(e), "Daemon: one that exits at start raises with its log", e)

a = daemon.arg_parser("it2nd", "plc").parse_args(["--it2nd", "x/it2nd", "--plc", "/bin/plc"])
R.check((a.it2nd, a.plc) == (os.path.abspath("x/it2nd"), "/bin/plc"), "arg_parser: --NAME PATH, absolute", a)
sf = os.path.join(T, "state-file")
R.check(daemon.file_sig(sf) is None, "file_sig: None for no file")
with open(sf, "w") as f:
    f.write("a")
s0 = daemon.file_sig(sf)
with open(sf + ".new", "w") as f:
    f.write("a")
os.replace(sf + ".new", sf)
R.check(s0 is not None and daemon.file_sig(sf) != s0, "file_sig: a file replaced by one of the same size differs")
d.conf = os.path.join(T, "atomic.conf")
os.symlink(sf, d.conf)
d.write_conf("x = 1\n", atomic=True)
R.check(not os.path.islink(d.conf) and open(d.conf).read() == "x = 1\n" and open(sf).read() == "a",
        "write_conf(atomic=True): renamed over the path (the old file untouched)")

# ---- broker
if broker.MOSQUITTO:
    bd = os.path.join(T, "mqtt")
    os.mkdir(bd)
    bp = ports.free_port()
    b = broker.Broker(bd, bp, "persistence false\nlistener %d 127.0.0.1\nallow_anonymous true\n" % bp)
    b.start()
    R.check(proc.wait_port(bp, timeout=1), "Broker: start returns once mosquitto listens")
    b.stop()
    R.check(b.p is None and not proc.wait_port(bp, timeout=0.3), "Broker: stop ends it")
else:
    R.skip("Broker: mosquitto is not installed (Debian package mosquitto)")

# ---- modbus: against a stand-in server that answers FC 04 with registers
# addr..addr+count-1, FC 16 with its echo, unit 9 with exception 0B, tid 99
# with a wrong tid
srv = socket.socket()
srv.bind(("127.0.0.1", 0))
srv.listen()


def serve():
    c = srv.accept()[0]
    try:
        while True:
            tid, _, length, unit = struct.unpack(">HHHB", modbus.recv_exact(c, 7))
            pdu = modbus.recv_exact(c, length - 1)
            if unit == 9:
                out = bytes([pdu[0] | 0x80, 0x0B])
            elif pdu[0] == 4:
                a, n = struct.unpack(">HH", pdu[1:5])
                out = bytes([4, 2 * n]) + struct.pack(">%dH" % n, *range(a, a + n))
            else:
                out = pdu[:5]
            c.sendall(modbus.mbap(tid + (1 if tid == 99 else 0), unit, out))
    except ConnectionError:
        c.close()


threading.Thread(target=serve, daemon=True).start()
ms = modbus.connect(srv.getsockname()[1])
R.check(modbus.read_regs(ms, 1, 10, 3, tid=5) == (10, 11, 12), "modbus: FC 04 read decoded")
R.check(modbus.write_regs(ms, 1, 40, [1, 2], tid=6) == "ok", "modbus: FC 16 write acknowledged")
R.check(modbus.read_regs(ms, 9, 0, 1, tid=7) == ("exc", 0x0B), "modbus: an exception reply is (exc, code)")
try:
    modbus.read_regs(ms, 1, 0, 1, tid=99)
    R.fail("modbus: a reply with another transaction id was taken")
except ValueError:
    R.ok("modbus: a reply with another transaction id raises ValueError")
ms.close()
srv.close()

# ---- testlib.sh
sh = os.path.join(T, "child.sh")
with open(sh, "w") as f:
    f.write('. %s/testlib.sh\ntl_init c\ntl_on_exit() { echo "hook ran"; }\n'
            'ok first\n[ "$1" = pass ] || fail second\nskip "no tool"\n'
            'P1=$(free_port); P2=$(free_port)\n[ "$P1" != "$P2" ] && ok "two ports $P1 $P2" || fail "same port"\n'
            '$TL_PY -c "import socket,time; s=socket.socket(); s.bind((\'127.0.0.1\',$P1)); s.listen(); '
            'time.sleep(3)" & LP=$!\n'
            'wait_port $P1 $LP && ok listened || fail "no listener"; kill $LP\n'
            'wait_port $P2 "" 4 && fail "P2 listened" || ok "P2 free"\necho "T=$T"\ntl_finish\n' % LIB)
rc, out, err = proc.run(["bash", sh, "fail"], timeout=60)
R.check(rc == 1 and "c: FAIL: second" in err and "c: ok: first" in out, "testlib.sh: a failed check: exit 1",
        "%d %s %s" % (rc, out, err))
tdir = re.search(r"^T=(.*)$", out, re.M).group(1)
R.check("hook ran" in out and os.path.isdir(tdir) and "logs kept in " + tdir in err,
        "testlib.sh: on failure tl_on_exit runs and the temp dir is kept", err)
R.check(PART_SKIP.findall(out) == ["no tool"], "testlib.sh: skip in the runner's words", out)
rc, out, err = proc.run(["bash", sh, "fail"], timeout=60, env=dict(os.environ, TL_FAIL_FAST="1"))
R.check(rc == 1 and "c: FAIL: second" in err and "two ports" not in out, "testlib.sh: TL_FAIL_FAST: exit 1 at the first failure",
        "%d %s" % (rc, out))
subprocess.run(["rm", "-rf", re.search(r"logs kept in (\S+)", err).group(1)])
rc, out, err = proc.run(["bash", sh, "pass"], timeout=60)
tdir2 = re.search(r"^T=(.*)$", out, re.M).group(1)
R.check(rc == 0 and "c: ok: listened" in out and "c: ok: P2 free" in out and "c: ok: two ports" in out,
        "testlib.sh: all passed: exit 0, free_port twice distinct, wait_port", "%d %s %s" % (rc, out, err))
R.check(not os.path.exists(tdir2), "testlib.sh: temp dir removed when all passed")
for body, want_rc, what in (("", 1, "no check and no skip: exit 1, 'no check ran'"),
                            ('skip "no tool"\n', 0, "only a skipped part: exit 0, said as a skip")):
    with open(sh, "w") as f:
        f.write(". %s/testlib.sh\ntl_init z\n%s echo T=$T\ntl_finish\n" % (LIB, body))
    rc, out, err = proc.run(["bash", sh], timeout=60)
    R.check(rc == want_rc and (("z: FAIL: no check ran" in err) == (want_rc == 1)), "testlib.sh: tl_finish, " + what,
            "%d %s %s" % (rc, out, err))
    subprocess.run(["rm", "-rf", re.search(r"^T=(.*)$", out, re.M).group(1)])
subprocess.run(["rm", "-rf", T, tdir])
sys.exit(R.finish())
