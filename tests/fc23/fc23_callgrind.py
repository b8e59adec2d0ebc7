#!/usr/bin/python3
"""User-space instructions per FC 23 request (issue 22): it2nd and the bare
libmodbus server each run under callgrind (instrumentation switched on
once the server listens, off before it stops), fc23_load sends FC 23
queries for a few seconds over N connections, and the instruction count is
divided by the requests answered. Unlike times, the count does not follow
the machine's load (other jobs on the shared cores), so it compares code
changes run to run; the epoll wake-ups a request shares with others vary a
little with the load (within about 1 %).

usage: fc23_callgrind.py --it2nd EXE --bare EXE --load EXE [--conns 1,8,32] [--seconds 2]

Prints one line per server and connection count; exit 1 when a server
does not start or an answer is wrong. Writes nothing outside a temporary
directory (no benchmark JSON: these are for profiling, the rows are
bench-fc23's).
"""
import argparse
import glob
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest.ports import free_port  # noqa: E402


def wait_port(p, port):
    for _ in range(600):
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
            return
        except OSError:
            if p.poll() is not None:
                break
            time.sleep(0.1)
    raise SystemExit("fc23_callgrind: server did not start under valgrind")


def one(a, which, conns, tmp):
    out = os.path.join(tmp, f"cg.{which}.{conns}")
    vg = ["valgrind", "--tool=callgrind", "--instr-atstart=no", "--callgrind-out-file=" + out]
    log = open(os.path.join(tmp, f"{which}.{conns}.log"), "w")
    if which == "it2nd":
        port = free_port()
        state = os.path.join(tmp, f"state.{conns}")
        os.makedirs(state)
        conf = os.path.join(tmp, f"it2nd.{conns}.conf")
        with open(conf, "w") as f:
            f.write("[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\n[modbus]\ntcp_listen = 127.0.0.1:%d\n"
                    "max_clients = %d\n[model:1]\nunit_id = 1\npreload = paper\n" % (state, port, conns + 8))
        p = subprocess.Popen(vg + [a.it2nd, "-c", conf, "--foreground"], stdout=log, stderr=subprocess.STDOUT)
        expect = "model"
    else:
        p = subprocess.Popen(vg + [a.bare, "0", "framed"], stdout=subprocess.PIPE, stderr=log, text=True)
        line = p.stdout.readline().split()
        if len(line) != 2 or line[0] != "port":
            raise SystemExit("fc23_callgrind: bare server did not start")
        port = int(line[1])
        expect = "pattern"
    try:
        wait_port(p, port)
        subprocess.run(["callgrind_control", "-i", "on", str(p.pid)], check=True, capture_output=True)
        r = subprocess.run([a.load, "--port", str(port), "--conns", str(conns), "--seconds", str(a.seconds),
                            "--expect", expect], capture_output=True, text=True, timeout=a.seconds + 120)
        subprocess.run(["callgrind_control", "-i", "off", str(p.pid)], check=True, capture_output=True)
        # The counts are written now: under callgrind, it2nd waiting in
        # io_uring_enter was seen not to act on the SIGTERM below.
        subprocess.run(["callgrind_control", "-d", str(p.pid)], check=True, capture_output=True)
    finally:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(30)
        log.close()
    d = dict(zip(r.stdout.split()[0::2], r.stdout.split()[1::2]))
    if r.returncode != 0 or "requests" not in d:
        raise SystemExit(f"fc23_callgrind: load against {which} failed: {r.stdout.strip()} {r.stderr[-300:]}")
    total = 0
    for f in glob.glob(out + "*"):
        with open(f) as fh:
            for line in fh:
                if line.startswith("totals:"):
                    total += int(line.split()[1])
    n = int(d["requests"])
    return total, n


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--bare", required=True)
    ap.add_argument("--load", required=True)
    ap.add_argument("--conns", default="1,8,32")
    ap.add_argument("--seconds", type=float, default=2.0)
    a = ap.parse_args()
    if not shutil.which("valgrind") or not shutil.which("callgrind_control"):
        print("fc23_callgrind: skip: valgrind not installed")
        return 0
    tmp = tempfile.mkdtemp(prefix="it2n-fc23cg.")
    try:
        for conns in [int(c) for c in a.conns.split(",")]:
            got = {w: one(a, w, conns, tmp) for w in ("it2nd", "bare")}
            per = {w: t / n for w, (t, n) in got.items()}
            print(f"fc23 callgrind, {conns:2d} connection(s): it2nd {per['it2nd']:6.0f} instructions per request "
                  f"({got['it2nd'][1]} requests), bare libmodbus {per['bare']:6.0f} ({got['bare'][1]}), "
                  f"ratio {per['it2nd'] / per['bare']:.2f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
