#!/usr/bin/python3
"""it2nd as a Sparkplug B edge node, checked from outside (issue 16 items 1,
2 and 4; docs/sparkplug.md): a real mosquitto on a free loopback port, the
real it2nd with a [sparkplug] section, a host application (paho-mqtt) that
decodes every payload with the protobuf wire decoder below (written from the
Sparkplug 3.0 field numbers, sharing nothing with the daemon's protoc-c
code), and pymodbus as the PLC.

Checks: NBIRTH/DBIRTH contents (metric names, datatypes, aliases, values
equal to what Modbus reads), seq and bdSeq rules, NDEATH as the will (QoS 1,
only bdSeq), DDATA by alias within 1 s of a Modbus write and a clear, NCMD
Rebirth (by name and by alias), broker SIGSTOP while Modbus is answered
promptly, kill -9 -> NDEATH with the session's bdSeq, restart -> bdSeq + 1,
broker restart -> reconnect and rebirth, SIGTERM -> one NDEATH then
DISCONNECT (no will after it), configuration errors with file:line.

usage: spb_test.py --it2nd PATH [--quick | --refusals | --no-refusals]
(--quick: births, DDATA, rebirth, SIGTERM only; for the sanitizer build.
--refusals: only the configuration errors, wrong password, TLS and ACL
refusals, which time nothing and so may share the machine with other
suites; --no-refusals: all but those, the part that times DDATA and Modbus
answers.) Prints "skip suite: why" and exits 0 when
mosquitto or paho-mqtt is missing."""
import argparse
import os
import queue
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import broker, report  # noqa: E402
from it2ntest.broker import MOSQUITTO  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402
try:
    import paho.mqtt.client as mqtt
except ImportError:
    mqtt = None

GROUP, NODE = "plant-a", "cell-7"
BS_N = 6  # model-3: B-spline, 6 x 6 intervals, type-1: a 9 x 9 net (81 values: by pages)
NODE_USER, NODE_PASSWORD = "cell-7", "correct horse battery"  # user = edge_node_id (the ACL)
ACL = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                   "examples", "sparkplug", "mosquitto.acl")
NS = "spBv1.0"
# Sparkplug datatypes (spec 6.4.16) the test names.
INT16, INT32, INT64, UINT16, UINT32, FLOAT, BOOLEAN, STRING, FLOATARRAY = 2, 3, 4, 6, 7, 9, 11, 12, 30

R = report.Report("sparkplug")  # spb_sf_test.py, which imports these helpers, renames it
check = R.check


# ---- protobuf wire format, from the encoding spec: (field << 3) | wire type

def varint(b, i):
    v, shift = 0, 0
    while True:
        if i >= len(b) or shift > 63:
            raise ValueError("truncated varint")
        c = b[i]
        i += 1
        v |= (c & 0x7F) << shift
        shift += 7
        if not c & 0x80:
            return v, i


def fields(b):
    """(field number, wire type, value) of a message; value: int (0), bytes
    (2), raw little-endian bytes (1: 8, 5: 4)."""
    i = 0
    while i < len(b):
        key, i = varint(b, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            v, i = varint(b, i)
        elif wt == 1:
            v, i = b[i:i + 8], i + 8
        elif wt == 2:
            n, i = varint(b, i)
            v, i = b[i:i + n], i + n
        elif wt == 5:
            v, i = b[i:i + 4], i + 4
        else:
            raise ValueError("wire type %d" % wt)
        if i > len(b):
            raise ValueError("truncated field %d" % num)
        yield num, wt, v


def decode_props(b):
    keys, vals = [], []
    for num, wt, v in fields(b):
        if num == 1:
            keys.append(v.decode())
        elif num == 2:
            pv = {}
            for n2, w2, v2 in fields(v):
                if n2 == 1:
                    pv["type"] = v2
                elif n2 == 8:
                    pv["value"] = v2.decode()
                elif n2 in (3, 4, 7):
                    pv["value"] = v2
            vals.append(pv)
    return dict(zip(keys, vals))


def decode_metric(b):
    m = {"fields": []}
    for num, wt, v in fields(b):
        m["fields"].append(num)
        if num == 1:
            m["name"] = v.decode()
        elif num == 2:
            m["alias"] = v
        elif num == 3:
            m["timestamp"] = v
        elif num == 4:
            m["datatype"] = v
        elif num == 5:
            m["is_historical"] = bool(v)
        elif num == 7:
            m["is_null"] = bool(v)
        elif num == 9:
            m["props"] = decode_props(v)
        elif num in (10, 11):
            m["raw"] = v
        elif num == 12:
            m["raw"] = struct.unpack("<f", v)[0]
            m["f32"] = bytes(v)
        elif num == 14:
            m["raw"] = bool(v)
        elif num == 15:
            m["raw"] = v.decode()
        elif num == 16:
            m["raw"] = bytes(v)
    return m


def decode_payload(b):
    p = {"metrics": [], "fields": [], "size": len(b)}
    for num, wt, v in fields(b):
        p["fields"].append(num)
        if num == 1:
            p["timestamp"] = v
        elif num == 2:
            p["metrics"].append(decode_metric(v))
        elif num == 3:
            p["seq"] = v
    return p


def value(m, dtype):
    """A metric's value under its datatype (Int8/16/32 travel as the 32-bit
    two's complement in a uint32)."""
    if m.get("is_null"):
        return None
    raw = m.get("raw")
    if dtype in (INT16, INT32):
        return raw - (1 << 32) if raw >= 1 << 31 else raw
    if dtype == INT64:
        return raw - (1 << 64) if raw >= 1 << 63 else raw
    return raw


def floats_le(b):
    """A FloatArray's bytes_value: packed little-endian float32 (spec 6.4.17)."""
    return list(struct.unpack("<%df" % (len(b) // 4), b))


def key(num, wt):
    return bytes([num << 3 | wt])


def enc_varint(v):
    out = bytearray()
    while True:
        c = v & 0x7F
        v >>= 7
        out.append(c | (0x80 if v else 0))
        if not v:
            return bytes(out)


def enc_len(num, b):
    return key(num, 2) + enc_varint(len(b)) + b


def ncmd_rebirth(by_alias=None):
    """An NCMD payload asking for a Rebirth: by name (datatype Boolean), or
    by the alias the NBIRTH gave."""
    ts = int(time.time() * 1000)
    if by_alias is None:
        m = enc_len(1, b"Node Control/Rebirth") + key(3, 0) + enc_varint(ts) + key(4, 0) + enc_varint(BOOLEAN)
    else:
        m = key(2, 0) + enc_varint(by_alias) + key(3, 0) + enc_varint(ts)
    m += key(14, 0) + enc_varint(1)
    return key(1, 0) + enc_varint(ts) + enc_len(2, m)


def dcmd_payload(metrics):
    """A DCMD payload: metrics as (name or None, alias or None, datatype,
    value); Float as float_value, integers as int_value (32-bit two's
    complement for negative Int32)."""
    ts = int(time.time() * 1000)
    out = key(1, 0) + enc_varint(ts)
    for name, alias, dt, v in metrics:
        m = b""
        if name is not None:
            m += enc_len(1, name.encode())
        if alias is not None:
            m += key(2, 0) + enc_varint(alias)
        m += key(3, 0) + enc_varint(ts)
        if name is not None:
            m += key(4, 0) + enc_varint(dt)
        if dt == FLOAT:
            m += key(12, 5) + struct.pack("<f", v)
        else:
            m += key(10, 0) + enc_varint(v & 0xFFFFFFFF)
        out += enc_len(2, m)
    return out


# ---- the worked examples of docs/sparkplug.md, rendered from the wire

TYPE_NAMES = {INT16: "Int16", INT32: "Int32", INT64: "Int64", UINT16: "UInt16", UINT32: "UInt32",
              FLOAT: "Float", BOOLEAN: "Boolean", STRING: "String", FLOATARRAY: "FloatArray"}
MFIELDS = {1: "name", 2: "alias", 3: "timestamp", 4: "datatype", 7: "is_null", 9: "properties", 10: "int_value",
           11: "long_value", 12: "float_value", 14: "boolean_value", 15: "string_value", 16: "bytes_value"}


def render(topic, qos, retain, p, aliases=None, pick=None, props=True):
    """A message as the docs show it: topic, QoS, then the payload as JSON
    with the protobuf field of each value; times as <ms>. aliases: names
    of DATA metrics (by alias) for the reader, as comments. pick: the
    indices of the metrics shown (the others are counted)."""
    out = ["topic %s   (QoS %d, %sretained)" % (topic, qos, "" if retain else "not "), "{"]
    if "timestamp" in p:
        out.append('  "timestamp": <ms>,')
    out.append('  "metrics": [')
    ms = p["metrics"]
    pick = range(len(ms)) if pick is None else [k for k in pick if k < len(ms)]
    last = -1
    for k in pick:
        m = ms[k]
        if k > last + 1:
            out.append("    ... %d metrics" % (k - last - 1))
        last = k
        dt = m.get("datatype")
        if dt is None and aliases and m.get("alias") in aliases:
            dt = aliases[m["alias"]][2]
        parts = []
        for f in m["fields"]:
            name = MFIELDS.get(f, "field%d" % f)
            if f == 1:
                parts.append('"name": "%s"' % m["name"])
            elif f == 2:
                parts.append('"alias": %d' % m["alias"])
            elif f == 3:
                parts.append('"timestamp": <ms>')
            elif f == 4:
                parts.append('"datatype": %d (%s)' % (dt, TYPE_NAMES.get(dt, "?")))
            elif f == 7:
                parts.append('"is_null": true')
            elif f == 9 and props:
                parts.append('"properties": {%s}' % ", ".join('"%s": "%s"' % (kk, vv.get("value"))
                                                           for kk, vv in m["props"].items()))
            elif f == 12:
                parts.append('"%s": %r' % (name, m["raw"]))
            elif f == 14:
                parts.append('"%s": %s' % (name, "true" if m["raw"] else "false"))
            elif f == 15:
                parts.append('"%s": "%s"' % (name, m["raw"]))
            elif f == 16:
                fl = floats_le(m["raw"])
                parts.append('"%s": <%d bytes: %s>' % (name, len(m["raw"]), ", ".join("%r" % x for x in fl[:4]) +
                                                         (", ..." if len(fl) > 4 else "")))
            elif f in (10, 11):
                v = value(m, dt)
                parts.append('"%s": %d%s' % (name, m["raw"], "" if v == m["raw"] else " (%d)" % v))
        note = ""
        if "name" not in m and aliases and m.get("alias") in aliases:
            note = "   // %s" % aliases[m["alias"]][1]
        out.append("    {%s}%s%s" % (", ".join(parts), "," if k + 1 < len(ms) else "", note))
    if last + 1 < len(ms):
        out.append("    ... %d metrics" % (len(ms) - last - 1))
    out.append("  ]" + ("," if "seq" in p else ""))
    if "seq" in p:
        out.append('  "seq": %d' % p["seq"])
    out.append("}")
    return "\n".join(out) + "\n"


def doc_blocks(path, samples, write):
    """Compare (or rewrite) every `<!-- spb:NAME -->` fenced block of path
    with the message rendered from this run. Returns the names that differ."""
    import re
    text = open(path).read()
    bad = []

    def sub(mo):
        name = mo.group(1)
        if name not in samples:
            bad.append(name + " (not captured)")
            return mo.group(0)
        new = "<!-- spb:%s -->\n```text\n%s```\n<!-- /spb:%s -->" % (name, samples[name], name)
        if new != mo.group(0):
            bad.append(name)
        return new
    text2 = re.sub(r"<!-- spb:(\w+) -->\n.*?<!-- /spb:\1 -->", sub, text, flags=re.S)
    if write and text2 != text:
        open(path, "w").write(text2)
    return bad


# ---- processes

def make_certs(d):
    """A test CA, a broker certificate for 127.0.0.1 and a client
    certificate signed by it, and a second CA that signed neither (EC keys:
    fast). Paths by name."""
    c = {k: os.path.join(d, k) for k in ("ca.crt", "ca.key", "ca2.crt", "ca2.key", "server.crt", "server.key",
                                          "client.crt", "client.key", "san.ext")}
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    with open(c["san.ext"], "w") as f:
        f.write("subjectAltName=IP:127.0.0.1\n")

    def run(*a):
        subprocess.run(["openssl"] + list(a), check=True, capture_output=True)
    for ca in ("ca", "ca2"):
        run("req", "-x509", *ec, "-keyout", c[ca + ".key"], "-out", c[ca + ".crt"], "-days", "2", "-subj",
            "/CN=spb-test-" + ca)
    for who, ext in (("server", ["-extfile", c["san.ext"]]), ("client", [])):
        csr = os.path.join(d, who + ".csr")
        run("req", *ec, "-keyout", c[who + ".key"], "-out", csr, "-subj", "/CN=" + who)
        run("x509", "-req", "-in", csr, "-CA", c["ca.crt"], "-CAkey", c["ca.key"], "-CAcreateserial", "-out",
            c[who + ".crt"], "-days", "2", *ext)
    for k in c:
        os.chmod(c[k], 0o644)  # the broker reads them as user mosquitto
    return c


class Broker(broker.Broker):
    """mosquitto with three loopback listeners: `port` anonymous (the host
    application), `node_port` for user NODE_USER with a password only,
    `tls_port` TLS with a client certificate required."""

    def __init__(self, d, port, node_port, tls_port, certs):
        self.node_port, self.tls_port = node_port, tls_port
        pw = os.path.join(d, "passwd")
        open(pw, "w").close()
        subprocess.run(["mosquitto_passwd", "-b", pw, NODE_USER, NODE_PASSWORD], check=True)
        # mosquitto started as root reads it as user mosquitto (a test secret)
        os.chmod(d, 0o755)
        os.chmod(pw, 0o644)
        super().__init__(d, port, "per_listener_settings true\npersistence false\n"
                         "listener %d 127.0.0.1\nallow_anonymous true\n"
                         "listener %d 127.0.0.1\nallow_anonymous false\npassword_file %s\nacl_file %s\n"
                         "listener %d 127.0.0.1\nallow_anonymous true\ncafile %s\ncertfile %s\nkeyfile %s\n"
                         "require_certificate true\n" % (port, node_port, pw, ACL, tls_port, certs["ca.crt"],
                                                        certs["server.crt"], certs["server.key"]),
                         wait_ports=(port, node_port), binary=MOSQUITTO)


class Host:
    """A Sparkplug host application: every message of the group, decoded,
    in arrival order."""

    def __init__(self, port):
        self.q = queue.Queue()
        self.sub = queue.Queue()
        self.c = mqtt.Client(client_id="spb-test-host-%d" % os.getpid(), clean_session=True,
                             protocol=mqtt.MQTTv311)
        self.c.on_message = lambda c, u, m: self.q.put((time.monotonic(), m.topic, bytes(m.payload), m.qos,
                                                        m.retain))
        self.c.on_subscribe = lambda c, u, mid, qos: self.sub.put(mid)
        self.c.connect("127.0.0.1", port, keepalive=30)
        self.c.loop_start()
        self.c.subscribe("%s/%s/#" % (NS, GROUP), qos=1)
        self.sub.get(timeout=5)

    def close(self):
        self.c.loop_stop()
        self.c.disconnect()

    def get(self, timeout):
        """The next message of the node (commands the host sent are
        skipped): (t, kind, device, payload dict, qos, retain) or None."""
        end = time.monotonic() + timeout
        while True:
            try:
                t, topic, raw, qos, retain = self.q.get(timeout=max(0.0, end - time.monotonic()))
            except queue.Empty:
                return None
            parts = topic.split("/")
            if parts[2] in ("NCMD", "DCMD"):
                continue
            return t, parts[2], parts[4] if len(parts) > 4 else None, decode_payload(raw), qos, retain

    def wait(self, kind, timeout, dev=None, log=None):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.get(end - time.monotonic())
            if m is None:
                return None
            if log is not None:
                log.append(m)
            if m[1] == kind and (dev is None or m[2] == dev):
                return m
        return None

    def dcmd(self, dev, metrics):
        self.c.publish("%s/%s/DCMD/%s/%s" % (NS, GROUP, NODE, dev), dcmd_payload(metrics), qos=0)

    def rebirth(self, by_alias=None):
        self.c.publish("%s/%s/NCMD/%s" % (NS, GROUP, NODE), ncmd_rebirth(by_alias), qos=0)


class Seq:
    """seq rules over the node's messages in arrival order: NBIRTH 0, every
    later NBIRTH/NDATA/DBIRTH/DDATA/DDEATH one more mod 256, NDEATH none.
    An NDEATH ends the session only when its bdSeq is the last NBIRTH's (a
    host ignores the will of an older session, spec 5.x)."""

    def __init__(self):
        self.last = None
        self.bd = None
        self.bad = []

    def feed(self, m):
        kind, p = m[1], m[3]
        if kind == "NDEATH":
            if "seq" in p:
                self.bad.append("NDEATH with seq %d" % p["seq"])
            if p["metrics"] and value(p["metrics"][0], INT64) == self.bd:
                self.last = None
            return
        s = p.get("seq")
        if kind == "NBIRTH":
            bd = [x for x in p["metrics"] if x.get("name") == "bdSeq"]
            self.bd = value(bd[0], INT64) if bd else None
            if s != 0:
                self.bad.append("NBIRTH seq %r" % s)
        elif self.last is None or s != (self.last + 1) % 256:
            self.bad.append("%s %s seq %r after %r" % (kind, m[2], s, self.last))
        self.last = s


def unit_kw(fn, unit):
    """pymodbus 3.0.0 takes unit=, its 3.0.0rc1 (Debian 12) slave=."""
    import inspect
    return {"slave" if "slave" in inspect.signature(fn).parameters else "unit": unit}


class Plc:
    def __init__(self, port):
        import logging
        from pymodbus.client import ModbusTcpClient
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
        t = time.monotonic() + 5
        while time.monotonic() < t:  # the daemon is starting
            try:
                socket.create_connection(("127.0.0.1", port), 0.2).close()
                break
            except OSError:
                time.sleep(0.05)
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
        assert self.c.connect(), "Modbus connect"

    def read(self, unit, addr, count):
        out = []
        while count:
            n = min(count, 120)
            r = self.c.read_holding_registers(addr, n, **unit_kw(self.c.read_holding_registers, unit))
            if r.isError():
                return None
            out += r.registers
            addr += n
            count -= n
        return out

    def write(self, unit, addr, regs):
        r = self.c.write_registers(addr, regs, **unit_kw(self.c.write_registers, unit))
        return not r.isError()

    def close(self):
        self.c.close()


STATUS = ["map_version", "state", "n", "m", "flags", "points_present", "points_required", "generation",
          "last_error", "last_error_i", "last_error_j", "last_error_fp", "points_received", "solves", "requests",
          "exceptions", "float_word_order", "coord_scale", "grid_rows", "grid_cols", "model_id", "grid_saturated",
          "int32_word_order", "kind", "net_rows", "net_cols", "points_present32", "points_required32"]
# Register address and type of each status field (docs/registers.md).
STATUS_REG = {"map_version": (0, "u16"), "state": (1, "u16"), "n": (2, "u16"), "m": (3, "u16"),
              "flags": (4, "u16"), "points_present": (5, "u16"), "points_required": (6, "u16"),
              "generation": (7, "u32"), "last_error": (9, "i16"), "last_error_i": (10, "i16"),
              "last_error_j": (11, "i16"), "last_error_fp": (12, "i16"), "points_received": (13, "u32"),
              "solves": (15, "u32"), "grid_rows": (23, "u16"), "grid_cols": (24, "u16"), "model_id": (25, "u16"),
              "grid_saturated": (26, "u16"), "kind": (28, "u16"), "net_rows": (29, "u16"), "net_cols": (30, "u16")}
DTYPE = {"u16": UINT16, "i16": INT16, "u32": UINT32}


def reg_value(regs, name):
    a, t = STATUS_REG[name]
    if t == "u32":
        return regs[a] << 16 | regs[a + 1]
    if t == "i16":
        return struct.unpack(">h", struct.pack(">H", regs[a]))[0]
    return regs[a]


def birth_table(p):
    return {m.get("name"): m for m in p["metrics"]}


def check_dbirth(m, plc, unit, rows, cols, aliases):
    """A DBIRTH: every metric named, aliased (unique on the node), typed,
    timestamped, described; values equal to what Modbus reads now."""
    dev, p = m[2], m[3]
    tab = birth_table(p)
    ok = all("name" in x and "alias" in x and "datatype" in x and "timestamp" in x for x in p["metrics"])
    check(ok, "%s DBIRTH: every metric has name, alias, datatype, timestamp" % dev)
    dup = [x["alias"] for x in p["metrics"] if x["alias"] in aliases]
    for x in p["metrics"]:
        aliases[x["alias"]] = (dev, x["name"], x["datatype"])
    check(not dup, "%s DBIRTH: aliases unique on the node (%d metrics)" % (dev, len(p["metrics"])))
    check(m[4] == 0 and not m[5], "%s DBIRTH QoS 0, not retained" % dev)
    check(all("description" in x.get("props", {}) for x in p["metrics"]), "%s DBIRTH: a description per metric" % dev)
    regs = plc.read(unit, 0, 32)
    bad = []
    for name, (a, t) in STATUS_REG.items():
        x = tab.get("Status/" + name)
        if x is None or x["datatype"] != DTYPE[t] or value(x, x["datatype"]) != reg_value(regs, name):
            bad.append("%s: %r vs Modbus %r" % (name, x and value(x, x["datatype"]), reg_value(regs, name)))
    check(not bad, "%s DBIRTH: status metrics equal the Modbus status block %s" % (dev, bad[:3]))
    check(all("Status/" + n in tab for n in STATUS), "%s DBIRTH: every status register has a metric" % dev)
    nodes = rows * cols
    grid = [tab.get("Sample Grid/r%d/c%d/%s" % (nd // cols, nd % cols, "TIF"[k])) for nd in range(nodes)
            for k in range(3)]
    check(all(g is not None and g["datatype"] == FLOAT for g in grid), "%s DBIRTH: %d sample grid metrics (Float)"
          % (dev, nodes * 3))
    if regs[1] == 2:
        fr = plc.read(unit, 8192, nodes * 6)
        want = [struct.pack(">HH", fr[2 * k], fr[2 * k + 1]) for k in range(nodes * 3)]
        got = [g and g.get("f32") and g["f32"][::-1] for g in grid]
        check(got == want, "%s DBIRTH: sample grid bit-equal to Modbus float32 registers 8192.." % dev)
    else:
        check(all(g and g.get("is_null") for g in grid), "%s DBIRTH: sample grid null while not solved" % dev)
    c32 = plc.read(unit, 88, 4)
    p32, r32 = tab.get("Status/points_present32"), tab.get("Status/points_required32")
    check(p32 is not None and r32 is not None and value(p32, UINT32) == c32[0] << 16 | c32[1] and
          value(r32, UINT32) == c32[2] << 16 | c32[3],
          "%s DBIRTH: Status/points_present32, points_required32 equal Modbus registers 88..91" % dev)
    check_nets(dev, tab, plc, unit, regs)
    check(p["size"] <= BIRTH_MAX, "%s DBIRTH: %d bytes (<= %d: every net above %d values goes by pages)"
          % (dev, p["size"], BIRTH_MAX, NET_MAX))
    return tab


FPS = ("LL", "LR", "L", "D", "R", "RL", "RR")
NET_MAX = 64           # values of a net carried whole (docs/sparkplug.md, "Nets")
BIRTH_MAX = 64 * 1024  # a DBIRTH stays below this whatever the model


def modbus_window(plc, unit, fp, ch, row, cols):
    """Row `row` of net (fp, ch) as float32 bytes (big-endian words, as
    Modbus sends them) through the page select and the coefficient window."""
    if not plc.write(unit, 96, [fp, ch, row]):
        return None
    r = plc.read(unit, 384, 2 * cols)
    return r and [struct.pack(">HH", r[2 * k], r[2 * k + 1]) for k in range(cols)]


def check_nets(dev, tab, plc, unit, regs):
    """Net/<FP>/<ch> (FloatArray, row-major) bit-equal to what Modbus reads:
    the control_net block (registers 2048.., Bezier) or the coefficient
    window (B-spline); null while not solved, for a footprint the model
    does not carry, and above NET_MAX values; Net/Page/values equal the
    window of the same page."""
    kind, nr, nc = regs[28], regs[29], regs[30]
    solved = regs[1] == 2
    nets = {(fp, ch): tab.get("Net/%s/%s" % (FPS[fp], "xyzTIF"[ch])) for fp in range(7) for ch in range(6)}
    if not check(all(x is not None and x["datatype"] == FLOATARRAY for x in nets.values()),
                 "%s DBIRTH: 42 Net/<FP>/<ch> metrics (FloatArray)" % dev):
        return
    if not solved or nr * nc > NET_MAX:
        check(all(x is not None and x.get("is_null") for x in nets.values()),
              "%s DBIRTH: nets null (%s)" % (dev, "not solved" if not solved else "%d x %d > %d values: by pages"
                                             % (nr, nc, NET_MAX)))
    else:
        bad = []
        for fp in range(7):
            if kind == 0:
                blk = plc.read(unit, 2048 + fp * 8 * 8 * 6 * 2, 8 * 8 * 6 * 2)
            for ch in range(6):
                x = nets[(fp, ch)]
                if kind == 0:
                    want = [struct.pack(">HH", *blk[((i * 8 + j) * 6 + ch) * 2:((i * 8 + j) * 6 + ch) * 2 + 2])
                            for i in range(nr) for j in range(nc)]
                else:
                    want = sum((modbus_window(plc, unit, fp, ch, r, nc) for r in range(nr)), [])
                got = x.get("raw")
                got = [got[4 * k:4 * k + 4][::-1] for k in range(len(got) // 4)] if got is not None else None
                if got != want and not (x.get("is_null") and not any(w != b"\0\0\0\0" for w in want)):
                    bad.append("%s/%s" % (FPS[fp], "xyzTIF"[ch]))
        check(not bad, "%s DBIRTH: every net (%d x %d) bit-equal to Modbus %s %s" %
              (dev, nr, nc, "control_net (2048..)" if kind == 0 else "coef_window", bad[:3]))
    pg = [tab.get("Net/Page/" + k) for k in ("fp", "ch", "row")]
    pv = tab.get("Net/Page/values")
    if not check(None not in pg and pv is not None, "%s DBIRTH: Net/Page/fp, ch, row, values" % dev):
        return
    pg = [value(x, UINT16) for x in pg]
    if solved:
        want = modbus_window(plc, unit, pg[0], pg[1], pg[2], nc)
        got = pv.get("raw")
        check(pv["datatype"] == FLOATARRAY and got is not None and
              [got[4 * k:4 * k + 4][::-1] for k in range(len(got) // 4)] == want,
              "%s DBIRTH: Net/Page/values (page %s) bit-equal to the Modbus coefficient window" % (dev, pg))
    else:
        check(pv.get("is_null"), "%s DBIRTH: Net/Page/values null while not solved" % dev)


def expect_births(host, seq, plc, devs, rows, cols, bdseq, why, timeout=10, ask_if_missed=False, before=None):
    log = []
    nb = host.wait("NBIRTH", timeout, log=log)
    if before is not None:
        before += log[:-1]
    if nb is None and ask_if_missed:
        host.rebirth()
        log = []
        nb = host.wait("NBIRTH", 5, log=log)
    if ask_if_missed:
        log = log[-1:]  # what came before this NBIRTH belongs to a sequence joined midway
    for x in log:
        seq.feed(x)
    fed = len(log)
    if not check(nb is not None, "%s: NBIRTH" % why):
        return None, {}
    p = nb[3]
    tab = birth_table(p)
    check(p.get("seq") == 0 and "timestamp" in p, "%s: NBIRTH seq 0 with a timestamp" % why)
    check(nb[4] == 0 and not nb[5], "%s: NBIRTH QoS 0, not retained" % why)
    bd = tab.get("bdSeq")
    check(bd is not None and bd["datatype"] == INT64, "%s: NBIRTH bdSeq metric (Int64)" % why)
    rb = tab.get("Node Control/Rebirth")
    check(rb is not None and rb["datatype"] == BOOLEAN and rb.get("raw") is False,
          "%s: NBIRTH Node Control/Rebirth = false (Boolean)" % why)
    got_bd = bd and value(bd, INT64)
    if bdseq is not None:
        check(got_bd == bdseq, "%s: NBIRTH bdSeq %r == %d" % (why, got_bd, bdseq))
    aliases = {x["alias"]: ("node", x["name"], x["datatype"]) for x in p["metrics"] if "alias" in x}
    check(len(aliases) == len(p["metrics"]), "%s: NBIRTH metrics each with an alias" % why)
    tabs, msgs = {}, {"NBIRTH": nb}
    # One DBIRTH per device, in the node's order (a model added by a
    # reload comes last).
    got, end = {}, time.monotonic() + 5
    while len(got) < len(devs) and time.monotonic() < end:
        m = host.wait("DBIRTH", end - time.monotonic(), log=log)
        if m is None:
            break
        got.setdefault(m[2], m)
    for x in log[fed:]:
        seq.feed(x)
    fed = len(log)
    for dev, unit in devs:
        m = got.get(dev)
        if check(m is not None, "%s: DBIRTH %s" % (why, dev)):
            tabs[dev] = check_dbirth(m, plc, unit, rows, cols, aliases)
            msgs[dev] = m
    check(not seq.bad, "%s: seq rules %s" % (why, seq.bad[:3]))
    return got_bd, {"aliases": aliases, "tabs": tabs, "nbirth": tab, "msgs": msgs}


def start_it2nd(args, conf):
    p = subprocess.Popen([args.it2nd, "-c", conf, "-f", "-v"], stdout=subprocess.DEVNULL,
                         stderr=open(conf + ".log", "a"))
    return p


def upload(i, j, fp, t, ind, f):
    # up_i, up_j, up_fp, x, y, z (i32 x coord_scale, ABCD), T, I, F x10000
    def i32(v):
        return [(v >> 16) & 0xFFFF, v & 0xFFFF]
    return [i, j, fp] + i32(i * 100) + i32(j * 100) + i32(0) + [t, ind, f]


def wait_death(host, seq, bd, timeout):
    """The NDEATH with bdSeq bd (wills of older sessions may come too)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        log = []
        m = host.wait("NDEATH", end - time.monotonic(), log=log)
        for x in log:
            seq.feed(x)
        if m is None or (m[3]["metrics"] and value(m[3]["metrics"][0], INT64) == bd):
            return m
    return None


def wait_ddata(host, seq, dev, aliases, metric, timeout):
    """The first DDATA of dev carrying metric (a DDATA of the request
    counters alone, from the 1 s scan after a read, may come first)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        log = []
        m = host.wait("DDATA", end - time.monotonic(), dev=dev, log=log)
        for x in log:
            seq.feed(x)
        if m is None or metric in ddata_values(m, aliases):
            return m
    return None


def ddata_values(m, aliases):
    out = {}
    for x in m[3]["metrics"]:
        dev, name, dt = aliases.get(x.get("alias"), (None, None, None))
        out[name] = value(x, dt) if dt is not None else "?"
    return out


def f32_list(regs):
    return [struct.unpack(">f", struct.pack(">HH", regs[2 * k], regs[2 * k + 1]))[0] for k in range(len(regs) // 2)]


RESULT_NAMES = ["Query/Result/%s/%s" % (fp, ch) for fp in FPS for ch in "xyzTIF"] + \
    ["Query/Summary/%s/%s" % (s_, k) for s_ in ("upper_min", "upper_max", "lower_min", "lower_max") for k in "TIF"]


def locate_and_pages(args, host, seq, plc, aliases, tab1, m_query, conf, samples, topic):
    """DCMD locate (Query/x, Query/y) on model-1 against a Modbus FC23 locate;
    a (u, w) and (x, y) mix refused; model-3 (B-spline 6 x 6, type-1) filled
    over Modbus, then a DCMD page select answered by Net/Page/values equal
    to the Modbus coefficient window; a page out of range refused."""
    known = {n: value(x, x["datatype"]) for n, x in tab1.items()}
    if m_query is not None:
        known.update(ddata_values(m_query, aliases))
    # The (x, y) of footprint D at (u, w) = (0.6, 0.3), from Modbus.
    rr = plc.c.readwrite_registers(read_address=128, read_count=108, write_address=66,
                                   write_registers=list(struct.unpack(">4H", struct.pack(">ff", 0.6, 0.3))),
                                   unit=1, slave=1)
    lx, ly = f32_list(rr.registers)[18:20]
    cmd = [("Query/x", None, FLOAT, lx), ("Query/y", None, FLOAT, ly)]
    samples["DCMD_LOCATE"] = render("%s/%s/DCMD/%s/model-1" % (NS, GROUP, NODE), 0, False,
                                    decode_payload(dcmd_payload(cmd)))
    host.dcmd("model-1", cmd)
    m = wait_ddata(host, seq, "model-1", aliases, "Query/x", 3)
    if check(m is not None, "DCMD locate (x, y) = (%.4g, %.4g) on model-1: DDATA" % (lx, ly)):
        v = ddata_values(m, aliases)
        known.update(v)
        rr = plc.c.readwrite_registers(read_address=128, read_count=108, write_address=74,
                                       write_registers=list(struct.unpack(">4H", struct.pack(">ff", lx, ly))),
                                       unit=1, slave=1)
        want = f32_list(rr.registers)
        qs = plc.read(1, 80, 6)
        f32 = lambda x: struct.unpack("<f", struct.pack("<f", x))[0]  # noqa: E731
        check(v.get("Query/kind") == 2 == qs[0] and v.get("Query/x") == f32(lx) and v.get("Query/y") == f32(ly) and
              "Query/u" in v and v["Query/u"] is None, "DCMD locate: Query/kind 2, Query/x, Query/y as sent, "
              "Query/u null (kind %r)" % v.get("Query/kind"))
        got = [known.get(n) for n in RESULT_NAMES]
        check(got == want, "DCMD locate: the 54 results equal a Modbus FC23 locate (q_x_f, q_y_f) (D: %r)"
              % got[18:21])
        check(known.get("Query/locate_fail") == qs[3] and known.get("Query/out_of_range") == qs[4] << 16 | qs[5],
              "DCMD locate: Query/locate_fail %r, out_of_range %r equal Modbus registers 83..85"
              % (known.get("Query/locate_fail"), known.get("Query/out_of_range")))
    host.dcmd("model-1", [("Query/u", None, FLOAT, 0.1), ("Query/x", None, FLOAT, lx)])
    time.sleep(0.3)
    check("Query/x: " not in open(conf + ".log").read() and
          "DCMD model-1 refused: a query is (u, w) or a locate (x, y), not both" in open(conf + ".log").read(),
          "DCMD mixing (u, w) and (x, y): refused and logged")

    # model-3: a B-spline, filled point by point over Modbus.
    for i in range(BS_N + 1):
        for j in range(BS_N + 1):
            plc.write(3, 40, upload(i, j, 3, 2000 + 500 * i + 300 * j, 1000 + 100 * (i + j), 3000 - 100 * i))
    m = wait_ddata(host, seq, "model-3", aliases, "Status/net_rows", 5)
    if check(m is not None, "model-3 (B-spline %dx%d) filled over Modbus: DDATA with Status/net_rows" % (BS_N, BS_N)):
        v = ddata_values(m, aliases)
        check(v.get("Status/state") == 2 and v.get("Status/net_rows") == BS_N + 3 and
              v.get("Status/net_cols") == BS_N + 3, "model-3: solved, a %d x %d coefficient net" % (BS_N + 3, BS_N + 3))
    cmd = [("Net/Page/fp", None, UINT16, 3), ("Net/Page/ch", None, UINT16, 3), ("Net/Page/row", None, UINT16, 4)]
    samples["DCMD_PAGE"] = render("%s/%s/DCMD/%s/model-3" % (NS, GROUP, NODE), 0, False,
                                  decode_payload(dcmd_payload(cmd)))
    host.dcmd("model-3", cmd)
    m = wait_ddata(host, seq, "model-3", aliases, "Net/Page/values", 3)
    if check(m is not None, "DCMD page select (D, T, row 4) on model-3: DDATA with Net/Page/values"):
        samples["DDATA_PAGE"] = render(topic(m), m[4], m[5], m[3], aliases=aliases)
        raw = [x.get("raw") for x in m[3]["metrics"] if aliases.get(x.get("alias"), (0, ""))[1] == "Net/Page/values"][0]
        want = modbus_window(plc, 3, 3, 3, 4, BS_N + 3)
        check(raw is not None and [raw[4 * k:4 * k + 4][::-1] for k in range(len(raw) // 4)] == want,
              "DCMD page select: Net/Page/values (%d floats) bit-equal to the Modbus coefficient window of page "
              "(3, 3, 4)" % (len(raw or b"") // 4))
    host.dcmd("model-3", [("Net/Page/row", None, UINT16, 300)])
    time.sleep(0.3)
    check("DCMD model-3: page select refused" in open(conf + ".log").read(),
          "DCMD page row 300 (> 257): refused and logged")


def config_errors(args, d):
    """[sparkplug] mistakes are fatal with file:line (it2nd -t)."""
    cases = [("bogus = 1", 6, "[sparkplug] bogus: unknown key"),
             ("primary_host_id = sca/da", 6, "[sparkplug] primary_host_id: expected"),
             ("store_forward_max = -1", 6, "[sparkplug] store_forward_max: expected a number of stored changes"),
             ("keepalive = 2", 6, "[sparkplug] keepalive: expected seconds 5..3600"),
             ("group_id = a/b", 6, "[sparkplug] group_id: expected")]
    for extra, line, want in cases:
        path = os.path.join(d, "bad.conf")
        with open(path, "w") as f:
            f.write("[daemon]\nstate_dir = %s/bad\n[sparkplug]\nbroker = 127.0.0.1:1\nedge_node_id = n\n%s\n"
                    % (d, extra))
            if "group_id" not in extra:
                f.write("group_id = g\n")
        r = subprocess.run([args.it2nd, "-t", "-c", path], capture_output=True, text=True)
        check(r.returncode != 0 and ("%s:%d: %s" % (path, line, want)) in r.stderr,
              "config: '%s' refused at %s:%d (%s)" % (extra, os.path.basename(path), line, r.stderr.strip()[-90:]))
    path = os.path.join(d, "bad.conf")
    with open(path, "w") as f:
        f.write("[sparkplug]\nbroker = 127.0.0.1:1883\ngroup_id = g\n")
    r = subprocess.run([args.it2nd, "-t", "-c", path], capture_output=True, text=True)
    check(r.returncode != 0 and "%s:2: [sparkplug] broker: edge_node_id is required" % path in r.stderr,
          "config: a missing edge_node_id is named with the section's first line")


def acl_confines(args, d, broker, host, pwfile):
    """examples/sparkplug/mosquitto.acl (docs/security.md): user cell-7
    publishing as another edge node gets nothing through."""
    conf, mb = os.path.join(d, "intruder.conf"), free_port()
    with open(conf, "w") as f:
        f.write("[daemon]\nstate_dir = %s/intruder\n[modbus]\ntcp_listen = 127.0.0.1:%d\n[sparkplug]\n"
                "broker = 127.0.0.1:%d\ngroup_id = %s\nedge_node_id = intruder\nusername = %s\n"
                "password_file = %s\n" % (d, mb, broker.node_port, GROUP, NODE_USER, pwfile))
    p = start_it2nd(args, conf)
    m = host.get(2.5)
    p.terminate()
    rc = p.wait(10)
    check(m is None and rc == 0, "ACL: user %s as edge node 'intruder': nothing published (%s)"
          % (NODE_USER, m and m[1]))


def wrong_password(args, d, broker, host):
    """A password the broker refuses: logged, never born, Modbus served, a
    clean stop (and no will: there was no session)."""
    pw, conf, mb = os.path.join(d, "wrong.password"), os.path.join(d, "wrong.conf"), free_port()
    with open(pw, "w") as f:
        f.write("not the password\n")
    with open(conf, "w") as f:
        f.write("[daemon]\nstate_dir = %s/wrong\n[modbus]\ntcp_listen = 127.0.0.1:%d\n[sparkplug]\n"
                "broker = 127.0.0.1:%d\ngroup_id = %s\nedge_node_id = wrong\nusername = %s\npassword_file = %s\n"
                "reconnect_max = 1\n" % (d, mb, broker.node_port, GROUP, NODE_USER, pw))
    p = start_it2nd(args, conf)
    plc = Plc(mb)
    ok = plc.read(1, 0, 28) is not None
    plc.close()
    m = host.get(2.5)
    p.terminate()
    rc = p.wait(10)
    log = open(conf + ".log").read()
    check(ok and m is None and rc == 0, "wrong password: no birth, Modbus served, exit 0")
    check("refused the connection" in log and "not authorised" in log,
          "wrong password: the refusal is logged (%s)" % [l for l in log.splitlines() if "refused" in l][:1])
    check(host.get(1.0) is None, "wrong password: no NDEATH either (no session was opened)")


def tls_checks(args, d, broker, host, certs):
    """TLS: files that do not load are configuration errors with file:line;
    with the test CA and a client certificate the node is born over TLS; a
    broker certificate from another CA, or no client certificate, and it is
    not (logged), while Modbus is served and the node stops cleanly."""
    conf = os.path.join(d, "tls.conf")

    def write(tls, node="tls-node"):
        mb = free_port()
        with open(conf, "w") as f:
            f.write("[daemon]\nstate_dir = %s/%s\n[modbus]\ntcp_listen = 127.0.0.1:%d\n[sparkplug]\n"
                    "broker = 127.0.0.1:%d\ngroup_id = %s\nedge_node_id = %s\nreconnect_max = 1\n%s"
                    % (d, node, mb, broker.tls_port, GROUP, node, tls))
        return mb
    bad = [("tls_cert = %s\n" % certs["client.crt"], 10, "[sparkplug] tls_cert: needs tls_key"),
           ("tls_ca = %s/none.crt\n" % d, 10, "[sparkplug] tls_ca: cannot open"),
           ("tls_ca = %s\n" % certs["san.ext"], 10, "[sparkplug] tls_ca: cannot load CA certificates"),
           ("tls_ca = %s\ntls_cert = %s\ntls_key = %s\n" % (certs["ca.crt"], certs["client.crt"], certs["ca.key"]), 12,
            "[sparkplug] tls_key: '%s' is not the key of tls_cert" % certs["ca.key"])]
    for tls, line, want in bad:
        write(tls)
        r = subprocess.run([args.it2nd, "-t", "-c", conf], capture_output=True, text=True)
        check(r.returncode != 0 and "%s:%d: %s" % (conf, line, want) in r.stderr,
              "TLS config refused at line %d: %s" % (line, r.stderr.strip()[-100:]))
    good = "tls_ca = %s\ntls_cert = %s\ntls_key = %s\n" % (certs["ca.crt"], certs["client.crt"], certs["client.key"])
    write(good)
    p = start_it2nd(args, conf)
    m = host.wait("NBIRTH", 8)
    check(m is not None and birth_table(m[3]).get("bdSeq") is not None,
          "TLS (server verified, client certificate): NBIRTH of tls-node")
    p.terminate()
    rc = p.wait(10)
    m = host.wait("NDEATH", 5)
    check(rc == 0 and m is not None, "TLS: SIGTERM -> NDEATH, exit 0")
    for tls, why, want in (("tls_ca = %s\ntls_cert = %s\ntls_key = %s\n" % (certs["ca2.crt"], certs["client.crt"],
                                                                         certs["client.key"]),
                            "a broker certificate from another CA", "certificate verify failed"),
                           ("tls_ca = %s\n" % certs["ca.crt"], "no client certificate", "libmosquitto: OpenSSL Error")):
        node = "tls-bad"
        mb = write(tls, node)
        open(conf + ".log", "w").close()
        p = start_it2nd(args, conf)
        plc = Plc(mb)
        ok = plc.read(1, 0, 28) is not None
        plc.close()
        m = host.get(2.5)
        p.terminate()
        rc = p.wait(10)
        log = open(conf + ".log").read()
        check(ok and m is None and rc == 0 and want in log,
              "TLS with %s: never born, Modbus served, exit 0, logged (%s)"
              % (why, [l for l in log.splitlines() if "libmosquitto" in l or "sparkplug: 127" in l][:1]))


class RefusalsDone(Exception):
    """--refusals: the refusals are checked, the node part is not run."""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--it2nd", required=True)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--refusals", action="store_true", help="only the refusals (no timing in them)")
    ap.add_argument("--no-refusals", action="store_true", help="all but the refusals")
    ap.add_argument("--doc", help="check the worked examples of this file (docs/sparkplug.md)")
    ap.add_argument("--write-doc", action="store_true", help="rewrite them instead")
    args = ap.parse_args()
    if not MOSQUITTO:
        print("skip suite: mosquitto is not installed (Debian package mosquitto; make deps)")
        return 0
    if mqtt is None:
        print("skip suite: paho-mqtt is not installed (Debian package python3-paho-mqtt; make deps)")
        return 0
    d = tempfile.mkdtemp(prefix="spb-test-")
    certs = make_certs(d)
    broker = Broker(d, free_port(), free_port(), free_port(), certs)
    node = host = plc = None
    try:
        broker.start()
        refusals = not args.quick and not args.no_refusals
        if refusals:
            config_errors(args, d)
        mbport = free_port()
        conf = os.path.join(d, "it2nd.conf")
        rows, cols = 3, 4

        pwfile = os.path.join(d, "node.password")
        with open(pwfile, "w") as f:
            f.write(NODE_PASSWORD + "\n")

        def write_conf(model2=True):
            with open(conf, "w") as f:
                f.write("[daemon]\nstate_dir = %s/state\n[modbus]\ntcp_listen = 127.0.0.1:%d\ngrid_rows = %d\n"
                        "grid_cols = %d\n[model:1]\npreload = paper\n%s[model:3]\nkind = bspline\nn = %d\nm = %d\n"
                        "type1 = yes\n"
                        "[sparkplug]\nbroker = 127.0.0.1:%d\ngroup_id = %s\nedge_node_id = %s\nkeepalive = 5\n"
                        "reconnect_max = 2\nusername = %s\npassword_file = %s\n"
                        % (d, mbport, rows, cols, "[model:2]\nn = 2\nm = 2\n" if model2 else "[model:2]\nremoved = yes\n",
                           BS_N, BS_N, broker.node_port,
                           GROUP, NODE, NODE_USER, pwfile))
        write_conf()
        devs = [("model-1", 1), ("model-2", 2), ("model-3", 3)]
        host = Host(broker.port)
        if refusals:
            wrong_password(args, d, broker, host)
            tls_checks(args, d, broker, host, certs)
            acl_confines(args, d, broker, host, pwfile)
        if args.refusals:
            raise RefusalsDone()
        seq = Seq()
        node = start_it2nd(args, conf)
        plc = Plc(mbport)
        bd0, st = expect_births(host, seq, plc, devs, rows, cols, 0, "first start")
        aliases = st["aliases"]
        samples = {}

        def topic(m):
            return "%s/%s/%s/%s%s" % (NS, GROUP, m[1], NODE, "/" + m[2] if m[2] else "")
        for name, sample in (("NBIRTH", "NBIRTH"), ("model-1", "DBIRTH")):
            m = st["msgs"].get(name)
            if m:
                names = [x.get("name") for x in m[3]["metrics"]]
                pick = None if name == "NBIRTH" else sorted(
                    list(range(9)) + [names.index(n) for n in ("Query/u", "Query/generation", "Query/Result/D/T",
                                                               "Upload/up_i", "Upload/up_T", "Sample Grid/r0/c0/T",
                                                               "Sample Grid/r0/c0/I", "Status/kind",
                                                               "Status/net_rows", "Status/points_present32",
                                                               "Query/x", "Query/kind", "Net/Page/fp",
                                                               "Net/Page/values", "Net/D/T") if n in names])
                samples[sample] = render(topic(m), m[4], m[5], m[3], pick=pick)
        samples["NCMD"] = render("%s/%s/NCMD/%s" % (NS, GROUP, NODE), 0, False, decode_payload(ncmd_rebirth()))

        # The reads of the DBIRTH checks moved the request counters: their
        # DDATA (the 1 s scan) first, so what follows is reproducible.
        for dev in ("model-1", "model-2", "model-3"):
            check(wait_ddata(host, seq, dev, aliases, "Status/requests", 3) is not None,
                  "%s: the request counters read by the test come as DDATA within the 1 s scan" % dev)

        # A Modbus write (an upload point into model 2): DDATA by alias in 1 s.
        t0 = time.monotonic()
        check(plc.write(2, 40, upload(0, 0, 3, 5000, 2000, 3000)), "Modbus: upload a point to model 2")
        m = wait_ddata(host, seq, "model-2", aliases, "Status/points_present", 3)
        if check(m is not None, "DDATA model-2 after the Modbus write"):
            check(m[0] - t0 <= 1.0, "DDATA model-2 %.3f s after the write request (<= 1 s)" % (m[0] - t0))
            check(all("name" not in x and "alias" in x and "timestamp" in x for x in m[3]["metrics"]),
                  "DDATA: metrics by alias only, timestamped")
            samples["DDATA"] = render(topic(m), m[4], m[5], m[3], aliases=aliases)
            v = ddata_values(m, aliases)
            regs = plc.read(2, 0, 28)
            check(v.get("Status/points_present") == 1 == reg_value(regs, "points_present") and
                  v.get("Status/state") == 1 and v.get("Status/points_received") == reg_value(regs, "points_received"),
                  "DDATA model-2 carries what changed: %s" % {k: v[k] for k in list(v)[:4]})
            check("Status/n" not in v, "DDATA model-2 leaves out what did not change")
        # DCMD: a query of model 1 (by name) answered in DDATA, bit-equal to
        # what a PLC reads for the same (u, w) with FC23.
        samples["DCMD"] = render("%s/%s/DCMD/%s/model-1" % (NS, GROUP, NODE), 0, False,
                                 decode_payload(dcmd_payload([("Query/u", None, FLOAT, 0.25),
                                                              ("Query/w", None, FLOAT, 0.5)])))
        host.dcmd("model-1", [("Query/u", None, FLOAT, 0.25), ("Query/w", None, FLOAT, 0.5)])
        m = wait_ddata(host, seq, "model-1", aliases, "Query/u", 3)
        m_query = m
        if check(m is not None, "DCMD query (u, w) = (0.25, 0.5) on model-1: DDATA"):
            samples["DDATA_QUERY"] = render(topic(m), m[4], m[5], m[3], aliases=aliases, pick=list(range(8)))
            v = ddata_values(m, aliases)
            rr = plc.c.readwrite_registers(read_address=128, read_count=108, write_address=66,
                                           write_registers=list(struct.unpack(">4H", struct.pack(">ff", 0.25, 0.5))),
                                           unit=1, slave=1)
            want = [struct.unpack(">f", struct.pack(">HH", rr.registers[2 * k], rr.registers[2 * k + 1]))[0]
                    for k in range(54)]
            got = [v.get("Query/Result/%s/%s" % (fp, ch)) for fp in ("LL", "LR", "L", "D", "R", "RL", "RR")
                   for ch in "xyzTIF"] + [v.get("Query/Summary/%s/%s" % (s_, k)) for s_ in
                                          ("upper_min", "upper_max", "lower_min", "lower_max") for k in "TIF"]
            check(v.get("Query/u") == 0.25 and v.get("Query/w") == 0.5 and got == want,
                  "DCMD query: the 54 results and summaries equal the Modbus FC23 answer (first %r)" % got[:2])
            check(v.get("Query/generation") == reg_value(plc.read(1, 0, 28), "generation"),
                  "DCMD query: Query/generation is the model's generation")
        # DCMD: a data point into model 2 by alias, the 9 Upload metrics:
        # journaled like a Modbus upload, its DDATA after the commit.
        ua = {n: a for a, (dv, n, dt) in aliases.items() if dv == "model-2" and n.startswith("Upload/")}
        pt = [("up_i", UINT16, 1), ("up_j", UINT16, 0), ("up_fp", UINT16, 3), ("up_x", INT32, -150),
              ("up_y", INT32, 0), ("up_z", INT32, 0), ("up_T", UINT16, 4000), ("up_I", UINT16, 1000),
              ("up_F", UINT16, 2000)]
        t0 = time.monotonic()
        host.dcmd("model-2", [(None, ua["Upload/" + n], dt, val) for n, dt, val in pt])
        m = wait_ddata(host, seq, "model-2", aliases, "Status/points_present", 3)
        regs, upb = plc.read(2, 0, 28), plc.read(2, 40, 12)
        if check(m is not None, "DCMD data point on model-2: DDATA"):
            v = ddata_values(m, aliases)
            check(m[0] - t0 <= 1.0 and v.get("Status/points_present") == 2 == reg_value(regs, "points_present"),
                  "DCMD data point: DDATA in %.3f s, points_present 2 (Modbus too)" % (m[0] - t0))
            check(v.get("Upload/up_i") == 1 and v.get("Upload/up_x") == -150 and upb[3:5] == [0xFFFF, 0xFF6A],
                  "DCMD data point: the upload block as written (up_x -150, as Modbus reads it)")
        # Half a data point: refused, nothing changes, last_error says so.
        host.dcmd("model-2", [("Upload/up_i", None, UINT16, 2)])
        m = wait_ddata(host, seq, "model-2", aliases, "Status/last_error", 3)
        check(m is not None and ddata_values(m, aliases).get("Status/last_error") == -1 and
              "Status/points_present" not in ddata_values(m, aliases) and
              reg_value(plc.read(2, 0, 28), "points_present") == 2,
              "DCMD half a data point: refused (last_error -1 in DDATA), nothing changed")
        host.dcmd("model-2", [("Status/state", None, UINT16, 0)])
        time.sleep(0.3)
        check("DCMD model-2 refused: Status/state: read-only" in open(conf + ".log").read(),
              "DCMD to a read-only metric: refused and logged")

        locate_and_pages(args, host, seq, plc, aliases, st["tabs"].get("model-1", {}), m_query, conf, samples, topic)

        # A clear of model 1 (command register 35 = 2): state 0, grid null.
        t1 = time.monotonic()
        check(plc.write(1, 35, [2]), "Modbus: clear model 1")
        m = wait_ddata(host, seq, "model-1", aliases, "Status/state", 3)
        if check(m is not None, "DDATA model-1 after the clear"):
            v = ddata_values(m, aliases)
            check(m[0] - t1 <= 1.0 and v.get("Status/state") == 0 and v.get("Status/points_present") == 0,
                  "DDATA model-1 in %.3f s: state 0, no points" % (m[0] - t1))
            check(v.get("Sample Grid/r0/c0/T", 1) is None and v.get("Sample Grid/r%d/c%d/F" % (rows - 1, cols - 1), 1)
                  is None, "DDATA model-1: sample grid metrics null once cleared")
        check(not seq.bad, "seq rules over DDATA %s" % seq.bad[:3])

        # NCMD Rebirth by name, then by alias: the same bdSeq, seq from 0.
        host.rebirth()
        expect_births(host, seq, plc, devs, rows, cols, bd0, "NCMD Rebirth (by name)")
        rb_alias = [a for a, v in aliases.items() if v[1] == "Node Control/Rebirth"]
        host.rebirth(by_alias=rb_alias[0])
        expect_births(host, seq, plc, devs, rows, cols, bd0, "NCMD Rebirth (by alias %d)" % rb_alias[0])

        if not args.quick:
            # SIGHUP with model 2 removed (removed = yes: a model holding
            # data goes only by the operator's explicit act): its DDEATH,
            # then a birth sequence without it; and with it again: born
            # again (empty: a removed model's data are discarded,
            # docs/daemon.md).
            write_conf(model2=False)
            node.send_signal(signal.SIGHUP)
            log = []
            m = host.wait("DDEATH", 5, dev="model-2", log=log)
            for x in log:
                seq.feed(x)
            check(m is not None and m[3].get("seq") is not None and not m[3]["metrics"],
                  "reload without model 2: DDEATH model-2 (seq, no metrics)")
            expect_births(host, seq, plc, devs[:1] + devs[2:], rows, cols, bd0, "reload without model 2")
            check(host.wait("DBIRTH", 0.5, dev="model-2") is None, "reload without model 2: no DBIRTH model-2")
            write_conf()
            node.send_signal(signal.SIGHUP)
            _, st = expect_births(host, seq, plc, devs, rows, cols, bd0, "reload with model 2 again")
            aliases = st["aliases"] or aliases

            # The broker stopped: Modbus is answered as promptly as ever.
            def modbus_for(seconds, write=None):
                lat, end = [], time.monotonic() + seconds
                while time.monotonic() < end:
                    a = time.monotonic()
                    r = plc.read(1, 0, 28) is not None
                    if write:
                        r = r and plc.write(*write)
                        write = None
                    lat.append(time.monotonic() - a if r else 99)
                    time.sleep(0.02)
                lat.sort()
                return lat
            base = modbus_for(1)
            broker.p.send_signal(signal.SIGSTOP)
            lat = modbus_for(3, (2, 40, upload(0, 1, 3, 6000, 1000, 2000)))
            broker.p.send_signal(signal.SIGCONT)
            check(len(lat) >= 20 and lat[-1] < 0.5, "broker SIGSTOPped 3 s: %d Modbus requests answered, median %.1f "
                  "ms, slowest %.1f ms (< 500 ms; broker running: median %.1f ms, slowest %.1f ms)"
                  % (len(lat), lat[len(lat) // 2] * 1000, lat[-1] * 1000, base[len(base) // 2] * 1000,
                     base[-1] * 1000))
            want = reg_value(plc.read(2, 0, 28), "points_present")
            m = wait_ddata(host, seq, "model-2", aliases, "Status/points_present", 8)
            check(m is not None and ddata_values(m, aliases).get("Status/points_present") == want,
                  "the change made while the broker was stopped arrives as DDATA once it runs (points_present %d)"
                  % want)

            # A broker silent for longer than the keep alive (5 s): the node
            # drops it and tries again (each CONNECT a new bdSeq); once the
            # broker runs, it sends the will of the first session and the
            # node is born again.
            broker.p.send_signal(signal.SIGSTOP)
            lat = modbus_for(14)
            broker.p.send_signal(signal.SIGCONT)
            check(lat[-1] < 0.5, "broker SIGSTOPped 14 s (keep alive 5 s): %d Modbus requests answered, slowest "
                  "%.1f ms" % (len(lat), lat[-1] * 1000))
            seen, log = [], []
            bdk, st = expect_births(host, seq, plc, devs, rows, cols, None, "after the broker was silent", timeout=20,
                                    before=seen)
            aliases = st["aliases"] or aliases
            check(bdk is not None and 1 <= (bdk - bd0) % 256 <= 20, "after the silence: NBIRTH with a new bdSeq "
                  "%r (was %d)" % (bdk, bd0))
            deaths = [x for x in seen if x[1] == "NDEATH"]
            m = deaths[0] if deaths else wait_death(host, seq, bd0, 5)
            if check(m is not None, "the broker sends the will of the silent session"):
                p = m[3]
                samples["NDEATH"] = render(topic(m), m[4], m[5], p)
                check(m[4] == 1 and not m[5], "NDEATH (the will) QoS 1, not retained")
                check(len(p["metrics"]) == 1 and p["metrics"][0].get("name") == "bdSeq" and
                      p["metrics"][0].get("datatype") == INT64 and "seq" not in p,
                      "NDEATH: only the bdSeq metric (Int64), no seq")
                check(value(p["metrics"][0], INT64) == bd0, "NDEATH bdSeq %r == the silent session's NBIRTH's %d"
                      % (value(p["metrics"][0], INT64), bd0))

            # kill -9: the broker sends the will, the NDEATH of this session.
            node.kill()
            node.wait()
            m = wait_death(host, seq, bdk, 5)
            check(m is not None and m[4] == 1, "kill -9: NDEATH (QoS 1) from the broker with the session's bdSeq %r"
                  % bdk)
            seq.last = None
            node = start_it2nd(args, conf)
            plc.close()
            plc = Plc(mbport)
            bd1, st = expect_births(host, seq, plc, devs, rows, cols, (bdk + 1) % 256, "restart after kill -9")
            aliases = st["aliases"] or aliases
            # The broker restarts: the node reconnects (backoff) and is born again.
            broker.stop()
            host.close()
            time.sleep(1.0)
            broker.start()
            host = Host(broker.port)
            seq.last = None
            # A host that subscribed after the node's NBIRTH asks for a Rebirth
            # (which keeps the bdSeq of the new session).
            expect_births(host, seq, plc, devs, rows, cols, (bd1 + 1) % 256, "broker restart", timeout=8,
                          ask_if_missed=True)
            bd_last = (bd1 + 1) % 256
        else:
            bd_last = bd0

        # SIGTERM: NDEATH (this session's bdSeq), then DISCONNECT: no will.
        node.terminate()
        rc = node.wait(10)
        m = host.wait("NDEATH", 5)
        check(rc == 0, "SIGTERM: it2nd exits 0")
        if check(m is not None, "SIGTERM: NDEATH published by the node"):
            check(value(m[3]["metrics"][0], INT64) == bd_last, "SIGTERM NDEATH bdSeq %r == %d"
                  % (value(m[3]["metrics"][0], INT64), bd_last))
        check(host.wait("NDEATH", 1.5) is None, "SIGTERM: one NDEATH only (DISCONNECT sent, the will discarded)")
        node = None
        if args.doc:
            bad = doc_blocks(args.doc, samples, args.write_doc)
            if args.write_doc:
                print("rewrote %s: %s" % (args.doc, ", ".join(bad) or "nothing changed"))
            else:
                check(not bad, "%s: the worked examples are what the node sends %s (tests/sparkplug/spb_test.py "
                      "--write-doc rewrites them)" % (args.doc, bad))
    except RefusalsDone:
        pass
    finally:
        if node is not None and node.poll() is None:
            node.kill()
            node.wait()
        if plc:
            plc.close()
        if host:
            host.close()
        broker.stop()
        if R.fails:
            for f in (os.path.join(d, "it2nd.conf.log"), broker.log):
                if os.path.exists(f):
                    print("---- %s" % f)
                    print(open(f).read()[-3000:])
        shutil.rmtree(d, ignore_errors=True)
    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
