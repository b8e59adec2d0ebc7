#!/usr/bin/python3
"""A fleet of it2nd edge nodes on one broker (issue 16 item 7; docs/fleet.md).

Starts a mosquitto on a free loopback port, a Sparkplug host application
(paho-mqtt, persistent session) and N it2nd nodes (each its own state_dir,
Modbus port and edge_node_id node-K, one small model: Bezier 1x1, a 2x2
sample grid), then:

  births   every node's NBIRTH and DBIRTH model-1 (the time from the first
           spawn to the last DBIRTH is a figure, target 10 s);
  pushes   ROUNDS rounds of one DCMD data point to every node at once;
           each answered by a DDATA of model-1 carrying the new
           Status/points_received (end-to-end latency DCMD publish ->
           DDATA at the host: p50, p99 target 1 s; DDATA/s);
  restart  the broker stopped and started: every node born again with a
           new bdSeq (time from the broker's start to the last DBIRTH,
           target 15 s);
  kill -9  KILL nodes killed: one NDEATH each whose bdSeq is that node's
           last NBIRTH's (time to the last one, target 5 s).

The payloads are decoded by spb_test.py's wire decoder (independent of the
daemon's protoc-c code). Functional failures (a missing birth, DDATA,
rebirth or NDEATH, a wrong bdSeq) fail the run; times are figures written
with --out as rows (tests/bench/mcu/results.py row(): met says whether the
target held), never asserted.

usage: spb_fleet.py --it2nd PATH [--nodes 100] [--kill 10] [--rounds 5]
                    [--out bench/fleet.json]
Prints "skip suite: why" and exits 0 when mosquitto or paho-mqtt is missing."""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "bench", "mcu"))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "lib"))
import spb_test as spb  # noqa: E402
from results import row  # noqa: E402
from it2ntest import broker, report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

GROUP = "fleet"
NS = "spBv1.0"
R = report.Report("fleet")
check = R.check


class Broker(broker.Broker):
    """mosquitto on one loopback port; persistence in its own directory so
    the host's persistent session (and the QoS 0 births queued for it while
    it reconnects) outlive a restart, as a site's host would configure it."""

    def __init__(self, d, port):
        pdir = os.path.join(d, "mqtt-db")
        os.makedirs(pdir)
        os.chmod(d, 0o755)
        os.chmod(pdir, 0o777)  # mosquitto started as root writes it as user mosquitto
        super().__init__(d, port, "listener %d 127.0.0.1\nallow_anonymous true\npersistence true\n"
                         "persistence_location %s/\nqueue_qos0_messages true\nmax_queued_messages 100000\n"
                         "max_inflight_messages 0\n" % (port, pdir))

    def start(self):
        return super().start(timeout=10.0)

    def stop(self):
        return super().stop(timeout=10.0)


class Host:
    """The host application: a persistent session (clean_session false,
    QoS 1 subscription) on spBv1.0/fleet/#; every node message decoded and
    kept with its arrival time."""

    def __init__(self, port):
        self.lock = threading.Condition()
        self.msgs = []
        self.port = port
        self.c = spb.mqtt.Client(client_id="fleet-host-%d" % os.getpid(), clean_session=False,
                                 protocol=spb.mqtt.MQTTv311)
        self.c.on_message = self.on_message
        self.c.on_connect = lambda c, u, f, rc: c.subscribe("%s/%s/#" % (NS, GROUP), qos=1)
        self.c.reconnect_delay_set(0.05, 0.2)
        self.connect()

    def connect(self):
        self.c.connect("127.0.0.1", self.port, keepalive=30)
        self.c.loop_start()

    def on_message(self, c, u, m):
        t = time.monotonic()
        parts = m.topic.split("/")
        if parts[2] in ("NCMD", "DCMD"):
            return
        try:
            p = spb.decode_payload(bytes(m.payload))
        except ValueError as e:
            p = {"metrics": [], "error": str(e)}
        with self.lock:
            self.msgs.append((t, parts[2], parts[3], parts[4] if len(parts) > 4 else None, p))
            self.lock.notify_all()

    def wait(self, pred, timeout):
        """Wait until pred(msgs) is true (it sees the list under the lock);
        returns its last result."""
        end = time.monotonic() + timeout
        with self.lock:
            while True:
                r = pred(self.msgs)
                if r or time.monotonic() >= end:
                    return r
                self.lock.wait(min(0.2, max(0.0, end - time.monotonic())))

    def dcmd(self, node, dev, payload):
        self.c.publish("%s/%s/DCMD/%s/%s" % (NS, GROUP, node, dev), payload, qos=0)

    def close(self):
        self.c.loop_stop()
        self.c.disconnect()


def node_conf(d, k, broker_port):
    sd = os.path.join(d, "node-%d" % k)
    os.makedirs(sd)
    path = os.path.join(sd, "it2nd.conf")
    with open(path, "w") as f:
        f.write("[daemon]\nstate_dir = %s/state\n[modbus]\ntcp_listen = 127.0.0.1:%d\ngrid_rows = 2\ngrid_cols = 2\n"
                "[model:1]\nn = 1\nm = 1\n[sparkplug]\nbroker = 127.0.0.1:%d\ngroup_id = %s\nedge_node_id = node-%d\n"
                "keepalive = 10\nreconnect_max = 2\n" % (sd, free_port(), broker_port, GROUP, k))
    return path


def explain(missing, procs, confs):
    """What a node that did not answer was doing: running or its exit
    status, and the end of its log (the first few such nodes)."""
    for nm in missing[:5]:
        print("  %s: %s; its log:" % (nm, "running" if procs[nm].poll() is None
                                      else "exited %d" % procs[nm].returncode))
        try:
            print("    " + "    ".join(open(confs[nm] + ".log").readlines()[-8:]))
        except OSError as e:
            print("    (%s)" % e)


def bdseq(p):
    for m in p["metrics"]:
        if m.get("name") == "bdSeq":
            return spb.value(m, spb.INT64)
    return None


def births_after(msgs, start, nodes):
    """node -> (NBIRTH bdSeq, time of its DBIRTH model-1) for births at or
    after index start; only a DBIRTH following its node's NBIRTH counts."""
    nb, out = {}, {}
    for t, kind, node, dev, p in msgs[start:]:
        if node not in nodes:
            continue
        if kind == "NBIRTH":
            nb[node] = bdseq(p)
            out.pop(node, None)
        elif kind == "DBIRTH" and dev == "model-1" and node in nb:
            out[node] = (nb[node], t, p)
    return out


def rss_kib(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def private_kib(pid):
    """Private_Clean + Private_Dirty: what this process alone costs."""
    n = 0
    try:
        with open("/proc/%d/smaps_rollup" % pid) as f:
            for line in f:
                if line.startswith(("Private_Clean:", "Private_Dirty:")):
                    n += int(line.split()[1])
    except OSError:
        return None
    return n


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q * (len(xs) - 1))))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--nodes", type=int, default=100)
    ap.add_argument("--kill", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", help="write the figures as rows to this JSON file (bench/fleet.json)")
    args = ap.parse_args()
    if not spb.MOSQUITTO:
        print("skip suite: mosquitto is not installed (Debian package mosquitto; make deps)")
        return 0
    if spb.mqtt is None:
        print("skip suite: paho-mqtt is not installed (Debian package python3-paho-mqtt; make deps)")
        return 0
    n, nkill = args.nodes, min(args.kill, args.nodes)
    names = ["node-%d" % k for k in range(n)]
    nodeset = set(names)
    d = tempfile.mkdtemp(prefix="spb-fleet-")
    broker = Broker(d, free_port())
    procs, host, figs = {}, None, {}
    try:
        broker.start()
        host = Host(broker.port)
        if not check(host.wait(lambda ms: host.c.is_connected(), 5), "host application connected"):
            return 1
        time.sleep(0.3)  # its SUBSCRIBE
        confs = {nm: node_conf(d, k, broker.port) for k, nm in enumerate(names)}

        # ---- births
        t0 = time.monotonic()
        t_start = {}
        for nm in names:
            t_start[nm] = time.monotonic()
            procs[nm] = subprocess.Popen([args.it2nd, "-c", confs[nm], "-f"], stdout=subprocess.DEVNULL,
                                         stderr=open(confs[nm] + ".log", "a"))
        t_spawned = time.monotonic() - t0
        got = host.wait(lambda ms: len(births_after(ms, 0, nodeset)) == n and births_after(ms, 0, nodeset), 30)
        got = got or births_after(host.msgs, 0, nodeset)
        check(len(got) == n, "births: NBIRTH + DBIRTH model-1 of %d/%d nodes (spawning took %.2f s)"
              % (len(got), n, t_spawned))
        if len(got) < n:
            explain(sorted(nodeset - set(got)), procs, confs)
            return 1
        figs["births_s"] = max(t for _, t, _ in got.values()) - t0
        figs["spawn_s"] = t_spawned  # part of births_s: starting 100 processes on a loaded machine
        figs["node_birth_max_s"] = max(t - t_start[nm] for nm, (_, t, _) in got.items())
        check(all(bd == 0 for bd, _, _ in got.values()), "births: every first NBIRTH has bdSeq 0")
        aliases = {}
        for nm, (_, _, p) in got.items():
            aliases[nm] = {m["alias"]: (m["name"], m["datatype"]) for m in p["metrics"]}
        rss = [rss_kib(procs[nm].pid) for nm in names]

        # ---- pushes: one DCMD data point per node per round, all at once
        lat, dd_count = [], 0
        t_push0 = time.monotonic()
        for r in range(args.rounds):
            i, j = r % 2, (r // 2) % 2
            pt = [("Upload/up_i", None, spb.UINT16, i), ("Upload/up_j", None, spb.UINT16, j),
                  ("Upload/up_fp", None, spb.UINT16, 3), ("Upload/up_x", None, spb.INT32, i * 100),
                  ("Upload/up_y", None, spb.INT32, j * 100), ("Upload/up_z", None, spb.INT32, 0),
                  ("Upload/up_T", None, spb.UINT16, 1000 + r), ("Upload/up_I", None, spb.UINT16, 2000),
                  ("Upload/up_F", None, spb.UINT16, 3000)]
            payload = spb.dcmd_payload(pt)
            start = len(host.msgs)
            sent = {}
            for nm in names:
                sent[nm] = time.monotonic()
                host.dcmd(nm, "model-1", payload)

            def answered(ms, start=start, want=r + 1):
                out = {}
                for t, kind, node, dev, p in ms[start:]:
                    if kind == "DDATA" and dev == "model-1" and node not in out:
                        for m in p["metrics"]:
                            name = aliases[node].get(m.get("alias"), (None,))[0]
                            if name == "Status/points_received" and m.get("raw") == want:
                                out[node] = t
                return out if len(out) == n else None
            res = host.wait(answered, 20) or answered(host.msgs) or {}
            got_r = res if res else {}
            if not got_r:
                # which nodes answered at all (the wait returned None)
                got_r = {}
                for t, kind, node, dev, p in host.msgs[start:]:
                    if kind == "DDATA" and dev == "model-1":
                        for m in p["metrics"]:
                            if aliases[node].get(m.get("alias"), (None,))[0] == "Status/points_received" and \
                                    m.get("raw") == r + 1:
                                got_r.setdefault(node, t)
            if not check(len(got_r) == n, "push round %d: a DDATA of model-1 with points_received %d from %d/%d "
                         "nodes" % (r + 1, r + 1, len(got_r), n)):
                explain(sorted(nodeset - set(got_r)), procs, confs)
            lat += [t - sent[nm] for nm, t in got_r.items()]
            dd_count += sum(1 for _, kind, _, _, _ in host.msgs[start:] if kind == "DDATA")
        t_push = time.monotonic() - t_push0
        if lat:
            figs["ddata_p50_ms"] = pct(lat, 0.5) * 1000
            figs["ddata_p99_ms"] = pct(lat, 0.99) * 1000
            figs["ddata_per_s"] = dd_count / t_push
        rss2 = [rss_kib(procs[nm].pid) for nm in names]
        priv = [x for x in (private_kib(procs[nm].pid) for nm in names) if x]

        # ---- broker restart: every node born again with a new bdSeq
        before = {nm: bd for nm, (bd, _, _) in got.items()}
        broker.stop()
        time.sleep(0.5)
        start = len(host.msgs)
        t_b = broker.start()
        reb = host.wait(lambda ms: len(births_after(ms, start, nodeset)) == n and births_after(ms, start, nodeset), 30)
        reb = reb or births_after(host.msgs, start, nodeset)
        if not check(len(reb) == n, "broker restart: %d/%d nodes reborn (NBIRTH + DBIRTH model-1)" % (len(reb), n)):
            explain(sorted(nodeset - set(reb)), procs, confs)
        badbd = [nm for nm, (bd, _, _) in reb.items() if not (bd is not None and 1 <= (bd - before[nm]) % 256 <= 20)]
        check(not badbd, "broker restart: every NBIRTH has a new bdSeq (%s)" % badbd[:5])
        if len(reb) == n:
            figs["reborn_s"] = max(t for _, t, _ in reb.values()) - t_b

        # ---- kill -9: one NDEATH per killed node, with its session's bdSeq
        victims = names[::max(1, n // nkill)][:nkill]
        last_bd = {nm: bd for nm, (bd, _, _) in reb.items()}
        start = len(host.msgs)
        t_k = time.monotonic()
        for nm in victims:
            procs[nm].kill()
        for nm in victims:
            procs[nm].wait()

        def deaths(ms):
            out = {}
            for t, kind, node, dev, p in ms[start:]:
                if kind == "NDEATH" and node in victims and node not in out and p["metrics"] and \
                        spb.value(p["metrics"][0], spb.INT64) == last_bd.get(node):
                    out[node] = t
            return out if len(out) == len(victims) else None
        dead = host.wait(deaths, 20) or {}
        if not dead:
            dead = {node: t for t, kind, node, dev, p in host.msgs[start:] if kind == "NDEATH" and node in victims
                    and p["metrics"] and spb.value(p["metrics"][0], spb.INT64) == last_bd.get(node)}
        check(len(dead) == len(victims), "kill -9 of %d nodes: %d NDEATHs with the bdSeq of their last NBIRTH"
              % (len(victims), len(dead)))
        others = [node for t, kind, node, dev, p in host.msgs[start:] if kind == "NDEATH" and node not in victims]
        check(not others, "kill -9: no NDEATH of a node still running (%s)" % others[:5])
        if len(dead) == len(victims):
            figs["ndeath_s"] = max(dead.values()) - t_k

        rss_ok = [x for x in rss2 if x]
        if rss_ok:
            figs["rss_mean_kib"] = statistics.fmean(rss_ok)
            figs["rss_max_kib"] = max(rss_ok)
            figs["rss_births_mean_kib"] = statistics.fmean([x for x in rss if x])
        if priv:
            figs["private_mean_kib"] = statistics.fmean(priv)
        for k, v in figs.items():
            print("  %s = %.1f" % (k, v))
        if args.out:
            rows = [row("fleet %d it2nd nodes: all NBIRTH + DBIRTH after start" % n, "s",
                        round(figs["births_s"], 2), target=10),
                    row("fleet slowest node: its spawn to its DBIRTH at the host", "s",
                        round(figs["node_birth_max_s"], 2)),
                    row("fleet DCMD data point -> DDATA at the host, p50 (%d pushes, %d at once)"
                        % (len(lat), n), "ms", round(figs["ddata_p50_ms"], 1)),
                    row("fleet DCMD data point -> DDATA at the host, p99 (%d pushes, %d at once)"
                        % (len(lat), n), "ms", round(figs["ddata_p99_ms"], 1), target=1000),
                    row("fleet DDATA delivered to the host during the push rounds", "messages/s",
                        round(figs["ddata_per_s"], 1)),
                    row("fleet RSS per it2nd node (mean, after the pushes)", "KiB", round(figs["rss_mean_kib"])),
                    row("fleet RSS per it2nd node (largest)", "KiB", figs["rss_max_kib"]),
                    row("fleet private memory per it2nd node (mean, smaps_rollup)", "KiB",
                        round(figs.get("private_mean_kib", 0))),
                    row("fleet broker restart: all %d nodes reborn (from the broker's start)" % n, "s",
                        round(figs["reborn_s"], 2), target=15),
                    row("fleet kill -9 of %d nodes: their NDEATHs (matching bdSeq) at the host" % nkill, "ms",
                        round(figs["ndeath_s"] * 1000, 1), target=5000)]
            out = {"conditions": {"cpus": os.cpu_count(), "loadavg_1min": round(os.getloadavg()[0], 2),
                                  "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                                  "note": ("tests/sparkplug/spb_fleet.py: %d it2nd (host build) on one mosquitto, "
                                           "loopback, one paho-mqtt host application; each node one Bezier 1x1 "
                                           "model, 2x2 sample grid; %d rounds of one DCMD data point per node sent "
                                           "at once; times measured at the host" % (n, args.rounds))},
                   "figures": {k: round(v, 3) for k, v in figs.items()},
                   "rows": rows}
            unmet = [r["name"] for r in rows if r["met"] is False]
            if unmet:
                out["reasons"] = {nm: "missed on this run (machine load %.1f): see conditions"
                                  % out["conditions"]["loadavg_1min"] for nm in unmet}
            with open(args.out, "w") as f:
                json.dump(out, f, indent=2, sort_keys=True)
                f.write("\n")
            print("wrote %s" % args.out)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.terminate()
        for p in procs.values():
            try:
                p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if host:
            host.close()
        broker.stop()
        if R.fails:
            print("---- %s (tail)" % broker.log)
            print(open(broker.log).read()[-1500:])
        shutil.rmtree(d, ignore_errors=True)
    print("fleet: %d nodes" % n)
    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
