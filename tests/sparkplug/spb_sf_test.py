#!/usr/bin/python3
"""it2nd's primary host and store-and-forward, checked from outside (issue
16 item 3; docs/sparkplug.md "Primary host and store-and-forward"): a real
mosquitto on a free loopback port, the real it2nd with primary_host_id and
store_forward_max, a host application that publishes its Sparkplug 3.0
STATE (retained JSON, QoS 1) and decodes every payload with spb_test.py's
own protobuf decoder, and pymodbus as the PLC.

Checks: no birth while the host's STATE says offline; PLC writes made then,
a kill -9 of it2nd with changes stored and a restart, more writes up to
store_forward_max and past it; the host online -> NBIRTH ("Store and
Forward/Dropped" = the overflow, also logged), DBIRTH with the current
values, then every stored change as DDATA in order, each metric
is_historical with its original timestamp, every written value present;
live DDATA after it not historical; a stale STATE (older timestamp) is
ignored; the host offline -> the node's NDEATH (its bdSeq) and silence, a
write meanwhile, online again -> a new session (bdSeq + 1) and that write as
history; the broker stopped, a write, broker and host back -> that write as
history; it2nctl spb watch/status/eval (--it2nctl). Prints "skip suite: why"
without mosquitto or paho-mqtt."""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spb_test as T  # noqa: E402  (the decoder, Host, Plc, helpers)

T.R.name = "spb-sf"

HOST_ID = "scada-1"
SF_MAX = 6


class Broker(T.broker.Broker):
    def __init__(self, d, port):
        super().__init__(d, port, "persistence false\nlistener %d 127.0.0.1\nallow_anonymous true\n" % port)


def state(host, online, ts, retain=True):
    """The primary host's STATE (Sparkplug 3.0: JSON, QoS 1, retained)."""
    host.c.publish("%s/STATE/%s" % (T.NS, HOST_ID), json.dumps({"online": online, "timestamp": ts}), qos=1,
                   retain=retain).wait_for_publish(5)


def drain(host, seq, secs):
    out = []
    end = time.monotonic() + secs
    while True:
        m = host.get(max(0.0, end - time.monotonic()))
        if m is None:
            return out
        seq.feed(m)
        out.append(m)


class Lines:
    """A process's stdout, line by line, with timeouts."""

    def __init__(self, argv):
        import queue
        import threading
        self.q = queue.Queue()
        self.p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.p.stdout:
            self.q.put(line.rstrip("\n"))

    def next(self, timeout):
        import queue
        try:
            return self.q.get(timeout=timeout)
        except queue.Empty:
            return None

    def expect(self, pred, timeout):
        """The first line whose fields satisfy pred (lines before it are
        returned too, for the message)."""
        end, seen = time.monotonic() + timeout, []
        while time.monotonic() < end:
            line = self.next(end - time.monotonic())
            if line is None:
                break
            seen.append(line)
            f = line.split(",")
            if len(f) == 7 and pred(f):
                return f, seen
        return None, seen

    def stop(self):
        if self.p.poll() is None:
            self.p.terminate()
        self.p.wait(5)


def ctl_checks(args, broker, mbport, plc, host_state):
    """it2nctl spb watch / status / eval against the node, compared with
    what it2nctl prints over Modbus."""
    check = T.check
    b = "127.0.0.1:%d" % broker.port
    w = Lines([args.it2nctl, "spb", "watch", "--broker", b, "--group", T.GROUP, "--node", T.NODE])
    try:
        check(w.next(5) == "time,node,device,event,bdseq,generation,state", "spb watch: CSV header")
        f, seen = w.expect(lambda f: f[1] == T.NODE and f[2] == "" and f[3] == "online", 5)
        check(f is not None, "spb watch: the node online (it asked for a Rebirth): %s" % seen[-1:])
        bd = int(f[4]) if f else None
        st = T.reg_value(plc.read(1, 0, 28), "generation")
        f, seen = w.expect(lambda f: f[2] == "model-1" and f[3] == "online", 5)
        check(f is not None and f[4] == str(bd) and f[5] == str(st) and f[6] == "solved",
              "spb watch: model-1 online, bdSeq %r, generation %r (Modbus %d), solved" % (
                  f and f[4], f and f[5], st))
        f, seen = w.expect(lambda f: f[2] == "model-2" and f[3] == "online", 5)
        check(f is not None and f[6] == "incomplete", "spb watch: model-2 online, incomplete")
        # An instrument's new value for a point of the solved model 1
        # (0,0,D: x -17, y 17 as in the paper; T 0.45): a new generation.
        regs = [0, 0, 3] + [0xFFFF, (-1700) & 0xFFFF, 0, 1700, 0, 0] + [4500, 7000, 2000]
        check(plc.write(1, 40, regs), "Modbus: a new value of point (0,0,D) of model 1")
        gen = T.reg_value(plc.read(1, 0, 28), "generation")
        f, seen = w.expect(lambda f: f[2] == "model-1" and f[3] == "generation", 5)
        check(f is not None and f[5] == str(gen) and gen == st + 1,
              "spb watch: model-1 generation %r == Modbus %d (was %d)" % (f and f[5], gen, st))

        def run(*a):
            return subprocess.run([args.it2nctl] + list(a), capture_output=True, text=True, timeout=20)
        at = ["--at", "0.25,0.5", "--at", "0.75,0.125", "--at", "1,0"]
        mb = run("eval", "--tcp", "127.0.0.1:%d" % mbport, "--unit", "1", "--summary", *at)
        sp = run("spb", "eval", "--broker", b, "--group", T.GROUP, "--node", T.NODE, "--model", "1", "--summary",
                 *at)
        check(mb.returncode == 0 and sp.returncode == 0 and sp.stdout == mb.stdout and mb.stdout.count("\n") > 20,
              "it2nctl spb eval prints what it2nctl eval prints over Modbus (%d lines; %s)" % (
                  sp.stdout.count("\n"), (sp.stderr or mb.stderr).strip()[:120]))
        mb = run("status", "--tcp", "127.0.0.1:%d" % mbport, "--unit", "1")
        sp = run("spb", "status", "--broker", b, "--group", T.GROUP, "--node", T.NODE, "--model", "1")
        check(mb.returncode == 0 and sp.returncode == 0 and sp.stdout == mb.stdout,
              "it2nctl spb status prints what it2nctl status prints (%r)" % sp.stdout.splitlines()[-1:])
        sp = run("spb", "eval", "--broker", b, "--group", T.GROUP, "--node", T.NODE, "--model", "2", "--at", "0,0")
        check(sp.returncode == 2 and "not solved" in sp.stderr, "spb eval of an unsolved model: exit 2, said why")
        sp = run("spb", "eval", "--broker", "127.0.0.1:%d" % T.free_port(), "--group", T.GROUP, "--node", T.NODE,
                 "--at", "0,0")
        check(sp.returncode == 3 and "broker" in sp.stderr, "spb eval, no broker there: exit 3 (%s)"
              % sp.stderr.strip()[:80])
        sp = run("spb", "eval", "--broker", b, "--group", T.GROUP, "--at", "0,0")
        check(sp.returncode == 1 and "--node" in sp.stderr, "spb eval without --node: usage error, exit 1")
        # The host goes offline: the node dies, its devices with it.
        host_state(False)
        f, seen = w.expect(lambda f: f[2] == "" and f[3] == "offline", 5)
        check(f is not None and f[4] == str(bd) and
              sum(1 for x in seen if x.split(",")[3:4] == ["offline"] and "model-" in x) == 2,
              "spb watch: model-1, model-2 and the node offline, bdSeq %r (%s)" % (f and f[4], seen))
        host_state(True)
        f, seen = w.expect(lambda f: f[2] == "" and f[3] == "online", 8)
        check(f is not None and bd is not None and int(f[4]) == (bd + 1) % 256,
              "spb watch: the node online again, bdSeq %r (a new session)" % (f and f[4]))
    finally:
        w.stop()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--it2nctl", help="also check it2nctl spb watch/status/eval")
    args = ap.parse_args()
    if not T.MOSQUITTO:
        print("skip suite: mosquitto is not installed (Debian package mosquitto; make deps)")
        return 0
    if T.mqtt is None:
        print("skip suite: paho-mqtt is not installed (Debian package python3-paho-mqtt; make deps)")
        return 0
    d = tempfile.mkdtemp(prefix="spb-sf-test-")
    broker = Broker(d, T.free_port())
    node = host = plc = None
    check = T.check
    try:
        broker.start()
        mbport = T.free_port()
        conf = os.path.join(d, "it2nd.conf")
        with open(conf, "w") as f:
            f.write("[daemon]\nstate_dir = %s/state\n[modbus]\ntcp_listen = 127.0.0.1:%d\ngrid_rows = 2\n"
                    "grid_cols = 2\n[model:1]\npreload = paper\n[model:2]\nn = 2\nm = 2\n"
                    "[sparkplug]\nbroker = 127.0.0.1:%d\ngroup_id = %s\nedge_node_id = %s\nkeepalive = 5\n"
                    "reconnect_max = 1\nprimary_host_id = %s\nstore_forward_max = %d\n"
                    % (d, mbport, broker.port, T.GROUP, T.NODE, HOST_ID, SF_MAX))
        host = T.Host(broker.port)
        seq = T.Seq()
        t0 = int(time.time() * 1000)
        state(host, False, t0)          # the host was there and went away
        node = T.start_it2nd(args, conf)
        plc = T.Plc(mbport)
        log = conf + ".log"
        # Connected (its log says so) but not born while the host is offline.
        end = time.monotonic() + 5
        while time.monotonic() < end and "sparkplug: connected" not in open(log).read():
            time.sleep(0.1)
        check("sparkplug: connected" in open(log).read(), "the node connects to the broker")
        msgs = drain(host, seq, 1.0)
        check(not [m for m in msgs if m[1] in ("NBIRTH", "DBIRTH", "DDATA")],
              "no birth and no data while the primary host's STATE is offline (%d messages)" % len(msgs))

        # PLC writes while the host is away; a kill -9 in the middle.
        written = []

        def write_point(k):
            t = 1000 + 100 * k
            ok = plc.write(2, 40, T.upload(k % 3, k // 3 % 3, 3, t, 2000, 3000))
            if ok:
                written.append(t)
            return ok
        for k in range(3):
            check(write_point(k), "host offline: PLC write %d" % k)
        time.sleep(0.3)
        sf = os.path.join(d, "state", "sparkplug.sf")
        check(os.path.exists(sf) and os.path.getsize(sf) > 0, "the changes are in state_dir/sparkplug.sf (%d bytes)"
              % (os.path.getsize(sf) if os.path.exists(sf) else -1))
        node.send_signal(signal.SIGKILL)
        node.wait(5)
        plc.close()
        node = T.start_it2nd(args, conf)
        plc = T.Plc(mbport)
        for k in range(3, SF_MAX + 2):  # SF_MAX stored, then 2 past the bound
            check(write_point(k), "host offline, after kill -9 and restart: PLC write %d" % k)
            time.sleep(0.05)
        time.sleep(0.5)
        text = open(log).read()
        check("store-and-forward full (store_forward_max = %d)" % SF_MAX in text,
              "the overflow is logged ('store-and-forward full')")
        msgs = drain(host, seq, 0.3)
        check(not [m for m in msgs if m[1] in ("NBIRTH", "DBIRTH", "DDATA")], "still nothing while offline")

        # The host comes back: births, then the history in order.
        t1 = int(time.time() * 1000)
        state(host, True, t1)
        nb = host.wait("NBIRTH", 5)
        if check(nb is not None, "host online: NBIRTH"):
            seq.feed(nb)
            tab = T.birth_table(nb[3])
            dr = tab.get("Store and Forward/Dropped")
            check(dr is not None and dr.get("raw") == 2, "NBIRTH Store and Forward/Dropped = 2 (the overflow), got %r"
                  % (dr and dr.get("raw")))
        msgs = drain(host, seq, 2.0)
        births = [m for m in msgs if m[1] == "DBIRTH"]
        check(len(births) == 2, "host online: 2 DBIRTH")
        aliases = {}
        for m in births:
            for x in m[3]["metrics"]:
                aliases[x["alias"]] = (m[2], x["name"], x["datatype"])
        b2 = [m for m in births if m[2] == "model-2"]
        if b2:
            v = {aliases[x["alias"]][1]: T.value(x, x["datatype"]) for x in b2[0][3]["metrics"]}
            check(v.get("Upload/up_T") == written[-1], "DBIRTH model-2 carries the last write (up_T %r)"
                  % v.get("Upload/up_T"))
        hist = [m for m in msgs if m[1] == "DDATA"]
        first_d = msgs.index(births[-1]) if births else 0
        check(all(msgs.index(m) > first_d for m in hist), "the history comes after the births")
        check(all(x.get("is_historical") for m in hist for x in m[3]["metrics"]),
              "every metric of the stored DDATA is_historical (%d DDATA)" % len(hist))
        ups = [T.ddata_values(m, aliases).get("Upload/up_T") for m in hist if m[2] == "model-2"]
        ups = [u for u in ups if u is not None]
        check(ups == written[:SF_MAX], "every value written while the host was away is in the history, in "
              "order: %r == %r" % (ups, written[:SF_MAX]))
        ts = [x["timestamp"] for m in hist for x in m[3]["metrics"]]
        check(ts == sorted(ts) and (not ts or ts[-1] < nb[3]["timestamp"]),
              "historical timestamps ascending, older than the NBIRTH")
        check(not seq.bad, "seq rules over births and history %s" % seq.bad[:3])
        time.sleep(0.3)
        check(not os.path.exists(sf) or os.path.getsize(sf) == 0, "the store is emptied once published")

        # A live change now: DDATA, not historical.
        check(write_point(SF_MAX + 2), "host online: PLC write")
        m = T.wait_ddata(host, seq, "model-2", aliases, "Upload/up_T", 3)
        if check(m is not None, "live DDATA after the history"):
            check(not any(x.get("is_historical") for x in m[3]["metrics"]), "a live DDATA is not historical")

        # A stale STATE (older timestamp, not retained): ignored.
        state(host, False, t0, retain=False)
        msgs = drain(host, seq, 1.0)
        check(not [m for m in msgs if m[1] == "NDEATH"], "a STATE older than the last one is ignored")

        # The host goes offline: NDEATH with the session's bdSeq, silence.
        bd = T.value(T.birth_table(nb[3])["bdSeq"], T.INT64) if nb else None
        state(host, False, int(time.time() * 1000))
        dm = T.wait_death(host, seq, bd, 5)
        check(dm is not None, "host offline: the node publishes its NDEATH (bdSeq %r)" % bd)
        time.sleep(0.5)
        check(write_point(SF_MAX + 3), "host offline again: PLC write")
        msgs = drain(host, seq, 1.0)
        check(not [m for m in msgs if m[1] in ("NBIRTH", "DDATA")], "no data while the host is offline")
        # Back with its clock a minute behind its own offline STATE: an
        # online STATE is taken whatever its timestamp (only offline ones
        # are compared, tck-id-operational-behavior-edge-node-birth-sequence-wait).
        t_back = int(time.time() * 1000) - 60000
        state(host, True, t_back)
        nb2 = host.wait("NBIRTH", 6)
        if check(nb2 is not None, "host online again (timestamp older than its offline STATE): NBIRTH"):
            seq.feed(nb2)
            bd2 = T.value(T.birth_table(nb2[3])["bdSeq"], T.INT64)
            check(bd is not None and bd2 > bd, "a new session: bdSeq %r > %r" % (bd2, bd))
        msgs = drain(host, seq, 1.5)
        hist = [m for m in msgs if m[1] == "DDATA" and all(x.get("is_historical") for x in m[3]["metrics"])]
        ups = [T.ddata_values(m, aliases).get("Upload/up_T") for m in hist if m[2] == "model-2"]
        check(written[-1] in ups, "the write made while the host was offline comes as history (%r)" % ups)
        # The late will of the session before (older than the online STATE
        # just taken): no disconnect (...-host-offline-timestamp); an offline
        # STATE with the online one's timestamp (its own will): NDEATH
        # (>=, tck-id-operational-behavior-edge-node-termination-host-offline).
        state(host, False, t_back - 1, retain=False)
        msgs = drain(host, seq, 0.5)
        check(not [m for m in msgs if m[1] == "NDEATH"], "an offline STATE older than the last online one: ignored")
        bd2 = T.value(T.birth_table(nb2[3])["bdSeq"], T.INT64) if nb2 else None
        state(host, False, t_back)
        check(T.wait_death(host, seq, bd2, 5) is not None, "an offline STATE with the online one's timestamp: NDEATH")
        state(host, True, int(time.time() * 1000))
        nb2b = host.wait("NBIRTH", 6)
        check(nb2b is not None, "host online: NBIRTH")
        # The broker goes away (its retained STATE with it): a write then is
        # kept too, and comes as history once broker and host are back.
        host.close()
        broker.stop()
        time.sleep(0.5)
        check(write_point(SF_MAX + 4), "broker stopped: PLC write")
        time.sleep(0.5)
        broker.start()
        host = T.Host(broker.port)
        state(host, True, int(time.time() * 1000))
        nb3 = host.wait("NBIRTH", 8)
        check(nb3 is not None, "broker back, host online: NBIRTH")
        msgs = drain(host, T.Seq(), 1.5)
        hist = [m for m in msgs if m[1] == "DDATA" and all(x.get("is_historical") for x in m[3]["metrics"])]
        ups = [T.ddata_values(m, aliases).get("Upload/up_T") for m in hist if m[2] == "model-2"]
        check(written[-1] in ups, "the write made while the broker was away comes as history (%r)" % ups)
        if args.it2nctl:
            ctl_checks(args, broker, mbport, plc, lambda on: state(host, on, int(time.time() * 1000)))
        node.send_signal(signal.SIGTERM)
        check(node.wait(10) == 0, "SIGTERM: exit status 0")
        node = None
    finally:
        if plc:
            plc.close()
        if node and node.poll() is None:
            node.kill()
            node.wait()
        if host:
            host.close()
        broker.stop()
        if T.R.fails:
            print("--- it2nd log ---")
            try:
                sys.stdout.write(open(os.path.join(d, "it2nd.conf.log")).read()[-4000:])
            except OSError:
                pass
        shutil.rmtree(d, ignore_errors=True)
    return T.R.finish()


if __name__ == "__main__":
    sys.exit(main())
