#!/usr/bin/python3
"""Interop traps of the Modbus map and the daemon's start-up checks, driven
the way a PLC integrator would: pymodbus 3.0.0 (unit=) and mbpoll against a
real it2nd on free loopback ports.

usage: interop_test.py IT2ND SIM_INSTRUMENT

* 32-bit integers follow int32_word_order (default: float_word_order), and
  the status register int32_word_order says which;
* the two views of each query input (q_u / q_u_f, ... q_y / q_y_f) agree
  after a write of either;
* TCP unit ids 0 and 255 reach the default model ([modbus] default_model:
  auto = the only model), 0B otherwise;
* --check-config refuses port 0, unresolvable hosts, duplicate keys, a
  default_model that is not configured, a bad int32_word_order, and names
  the reason of a missing file;
* at -v, link CONFIGURE/PUT/COMMIT and each solve are logged, and start-up
  logs the model's state after the WAL replay (never "empty" first).
"""
import logging
import os
import struct
import subprocess
import sys
import tempfile

from pymodbus.client import ModbusTcpClient

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import daemon, report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

logging.disable(logging.CRITICAL)  # pymodbus 3.0.0 logs about unit=
IT2ND, INSTR = (os.path.abspath(a) for a in sys.argv[1:3])
PAPER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..",
                     "examples", "paper_4x4.csv")
T = tempfile.mkdtemp(prefix="it2n-interop.")
R = report.Report("interop", quiet_ok=True)  # only failures are printed
check = R.check


class Daemon(daemon.Daemon):
    """A fresh it2nd (state T/NAME.state unless given) with body after
    [modbus], listening, and a pymodbus client connected to it."""

    def __init__(self, body, name, state=None):
        super().__init__(IT2ND, os.path.join(T, name + ".conf"), os.path.join(T, name + ".log"),
                         port=free_port())
        self.state = state or os.path.join(T, name + ".state")
        self.write_conf(daemon.basic_conf(self.state, self.port, body,
                                          "snapshot_interval = 3600\nlink_backoff_max = 1\n"))
        self.start()
        self.c = ModbusTcpClient("127.0.0.1", port=self.port)
        self.c.connect()

    def stop(self):
        self.c.close()
        return super().stop(20)


def regs(r):
    return None if r.isError() else r.registers


def exc(r):
    return getattr(r, "exception_code", None) if r.isError() else None


def f32(words, order):
    """Decode two registers as float32 in ABCD or CDAB."""
    if order == "CDAB":
        words = [words[1], words[0]]
    return struct.unpack(">f", struct.pack(">HH", *words))[0]


def w32(value, order, fmt=">i"):
    hi, lo = struct.unpack(">HH", struct.pack(fmt, value))
    return [lo, hi] if order == "CDAB" else [hi, lo]


def u32(words, order):
    hi, lo = (words[1], words[0]) if order == "CDAB" else words
    return (hi << 16) | lo


def i32(words, order):
    v = u32(words, order)
    return v - (1 << 32) if v >= 1 << 31 else v


def mbpoll(port, unit, ref, count):
    p = subprocess.run(["mbpoll", "-m", "tcp", "-a", str(unit), "-0", "-r",
                        str(ref), "-c", str(count), "-t", "3", "-1",
                        "127.0.0.1", "-p", str(port)],
                       capture_output=True, text=True, timeout=30)
    vals = [int(ln.split()[1]) for ln in p.stdout.splitlines()
            if ln.startswith("[")]
    return p.returncode, vals


def word_orders():
    # float CDAB, ints follow (the default int32_word_order = float)
    d = Daemon("float_word_order = CDAB\n", "cdab")
    st = regs(d.c.read_input_registers(0, 28, unit=1))
    check(st is not None and st[21] == 1 and st[27] == 1,
          f"CDAB: float_word_order and int32_word_order status = 1 ({st and st[21:28]})")
    gen0 = u32(st[7:9], "CDAB")
    check(gen0 == 1, f"CDAB: generation of the preloaded model decodes as 1 in CDAB, got {gen0}")
    # Upload point (0,0,LL) again with x, y as i32 CDAB (the paper's -23, 11).
    up = [0, 0, 0] + w32(-2300, "CDAB") + w32(1100, "CDAB") + w32(0, "CDAB") + [4000, 7000, 2000]
    check(not d.c.write_registers(40, up, unit=1).isError(), "CDAB: upload of (0,0,LL) with i32 CDAB accepted")
    st = regs(d.c.read_input_registers(0, 28, unit=1))
    check(u32(st[7:9], "CDAB") == gen0 + 1, f"CDAB: generation +1 after the upload ({st[7:9]})")
    # Query at (0, 0): LL's x as scaled i32 (CDAB) and as float (CDAB).
    r = regs(d.c.readwrite_registers(read_address=256, read_count=9, write_address=64,
                                     write_registers=[0, 0], unit=1))
    rf = regs(d.c.read_holding_registers(128, 4, unit=1))
    check(r is not None and i32(r[0:2], "CDAB") == -2300 and i32(r[2:4], "CDAB") == 1100,
          f"CDAB: results_scaled LL x, y = -2300, 1100 as i32 CDAB ({r and r[0:4]})")
    check(rf is not None and abs(f32(rf[0:2], "CDAB") + 23) < 1e-4 and abs(f32(rf[2:4], "CDAB") - 11) < 1e-4,
          f"CDAB: results_f32 LL x, y = -23, 11 ({rf})")
    qs = regs(d.c.read_holding_registers(80, 6, unit=1))
    check(qs is not None and u32(qs[1:3], "CDAB") == gen0 + 1, f"CDAB: q_generation in CDAB ({qs})")
    query_views(d, "CDAB")
    d.stop()
    # Integers kept high word first, floats CDAB: both documented, both said.
    d = Daemon("float_word_order = CDAB\nint32_word_order = ABCD\n", "mixed")
    st = regs(d.c.read_input_registers(0, 28, unit=1))
    check(st[21] == 1 and st[27] == 0 and u32(st[7:9], "ABCD") == 1,
          f"int32_word_order = ABCD: status 0, generation high word first ({st[7:9]}, {st[27]})")
    d.stop()


def query_views(d, order):
    c = d.c
    # q_u, q_w written (x10000): the float views read the same u, w.
    c.write_registers(64, [2500, 7500], unit=1)
    q = regs(c.read_holding_registers(64, 14, unit=1))
    check(abs(f32(q[2:4], order) - 0.25) < 1e-7 and abs(f32(q[4:6], order) - 0.75) < 1e-7,
          f"{order}: after q_u, q_w = 2500, 7500: q_u_f, q_w_f = {f32(q[2:4], order)}, {f32(q[4:6], order)}")
    # q_u_f written: q_u reads the new u rounded to x10000.
    fw = list(struct.unpack(">HH", struct.pack(">f", 0.123456)))
    if order == "CDAB":
        fw = [fw[1], fw[0]]
    res = regs(c.readwrite_registers(read_address=64, read_count=6, write_address=66,
                                     write_registers=fw, unit=1))
    check(res is not None and res[0] == 1235 and res[1] == 7500 and res[2:4] == fw,
          f"{order}: after q_u_f = 0.123456 (FC 23): q_u = 1235, q_w kept, q_u_f as written ({res})")
    # q_x scaled written: q_x_f reads x; q_y_f written: q_y reads y x coord_scale.
    c.write_registers(70, w32(-1750, order), unit=1)
    q = regs(c.read_holding_registers(70, 8, unit=1))
    check(abs(f32(q[4:6], order) + 17.5) < 1e-6, f"{order}: after q_x = -1750: q_x_f = {f32(q[4:6], order)}")
    fw = list(struct.unpack(">HH", struct.pack(">f", 3.25)))
    if order == "CDAB":
        fw = [fw[1], fw[0]]
    c.write_registers(76, fw, unit=1)
    q = regs(c.read_holding_registers(70, 8, unit=1))
    check(i32(q[2:4], order) == 325 and i32(q[0:2], order) == -1750,
          f"{order}: after q_y_f = 3.25: q_y = {i32(q[2:4], order)} (325), q_x kept {i32(q[0:2], order)}")


def same_status(a, b):
    """Status blocks equal but for the request counter (17..18), which
    every read bumps."""
    return a is not None and b is not None and a[:17] == b[:17] and a[19:] == b[19:]


def default_unit():
    d = Daemon("", "single")
    want = regs(d.c.read_input_registers(0, 28, unit=1))
    for u in (0, 255):
        r0 = u32(regs(d.c.read_input_registers(17, 2, unit=1)), "ABCD")
        got = regs(d.c.read_input_registers(0, 28, unit=u))
        r1 = u32(regs(d.c.read_input_registers(17, 2, unit=1)), "ABCD")
        check(same_status(got, want) and r1 == r0 + 2,
              f"single model: pymodbus unit {u} reads model 1's status, counted as its request ({got and got[:4]}, {r0} -> {r1})")
        rc, vals = mbpoll(d.port, u, 0, 28)
        check(rc == 0 and same_status(vals, want), f"single model: mbpoll -a {u} reads model 1's status (rc {rc})")
        # The default model takes writes too (FC 23 query).
        r = regs(d.c.readwrite_registers(read_address=256 + 27 + 6, read_count=3, write_address=64,
                                         write_registers=[5000, 5000], unit=u))
        check(r == [6738, 4645, 1617], f"single model: FC 23 on unit {u} answers D at (0.5, 0.5) ({r})")
    check(exc(d.c.read_input_registers(0, 1, unit=7)) == 0x0B, "single model: unit 7 still answers 0B")
    d.stop()
    two = "[model:1]\nunit_id = 1\npreload = paper\n[model:2]\nunit_id = 2\nn = 2\nm = 2\n"
    d = Daemon(two, "two")
    check(exc(d.c.read_input_registers(0, 1, unit=255)) == 0x0B and
          exc(d.c.read_input_registers(0, 1, unit=0)) == 0x0B,
          "two models, default_model = auto: units 0 and 255 answer 0B")
    rc, _ = mbpoll(d.port, 255, 0, 1)
    check(rc != 0, "two models: mbpoll -a 255 fails")
    d.stop()
    d = Daemon("default_model = 2\n" + two, "two-default")
    st = regs(d.c.read_input_registers(0, 28, unit=255))
    check(st is not None and st[25] == 2 and st[2] == 2, f"default_model = 2: unit 255 reaches model 2 ({st and st[25]})")
    d.stop()
    d = Daemon("default_model = none\n", "none")
    check(exc(d.c.read_input_registers(0, 1, unit=255)) == 0x0B, "default_model = none: unit 255 answers 0B")
    check(regs(d.c.read_input_registers(0, 1, unit=1)) == [1], "default_model = none: unit 1 served")
    d.stop()


def check_config():
    cases = [
        ("[modbus]\ntcp_listen = 127.0.0.1:0\n", ":2: [modbus] tcp_listen: port 0: expected a port 1..65535"),
        ("[modbus]\n\ntcp_listen = plc.invalid:1502\n", ":3: [modbus] tcp_listen: cannot resolve host 'plc.invalid'"),
        ("[listen:a]\naddress = nohost.invalid:1502\n", ":2: [listen:a] address: cannot resolve host 'nohost.invalid'"),
        ("[modbus]\ncoord_scale = 10\ngrid_rows = 4\ncoord_scale = 100\n",
         ":4: [modbus] coord_scale: duplicate key (first set on line 2)"),
        ("[modbus]\ndefault_model = 9\n", ":2: [modbus] default_model: no [model:9] is configured"),
        ("[modbus]\nint32_word_order = BE\n",
         ":2: [modbus] int32_word_order: expected float, ABCD, CDAB, BADC or DCBA"),
    ]
    for k, (text, want) in enumerate(cases):
        path = os.path.join(T, f"bad{k}.conf")
        open(path, "w").write(text)
        p = subprocess.run([IT2ND, "-c", path, "--check-config"], capture_output=True, text=True, timeout=30)
        check(p.returncode == 1 and (path + want) in p.stderr,
              f"--check-config {text!r}: exit {p.returncode}, {p.stderr.strip()!r}, want {want!r}")
    missing = os.path.join(T, "no-such.conf")
    p = subprocess.run([IT2ND, "-c", missing, "--check-config"], capture_output=True, text=True, timeout=30)
    check(p.returncode == 1 and f"{missing}: cannot open: No such file or directory" in p.stderr,
          f"missing config: {p.stderr.strip()!r}")
    good = os.path.join(T, "good.conf")
    # free ports and a scratch state_dir: --check-config also binds the
    # ports and writes in state_dir (issue 18)
    open(good, "w").write("[daemon]\nstate_dir = %s\n[modbus]\ntcp_listen = localhost:%d\ntcp_listen = [::1]:%d\n"
                          "int32_word_order = float\ndefault_model = 1\n"
                          % (os.path.join(T, "good.state"), free_port(), free_port()))
    p = subprocess.run([IT2ND, "-c", good, "--check-config"], capture_output=True, text=True, timeout=30)
    check(p.returncode == 0, f"localhost, a repeated tcp_listen, int32_word_order/default_model pass: {p.stderr!r}")


def verbose_log():
    state = os.path.join(T, "link.state")
    link = os.path.join(T, "inst0")
    body = ("[model:1]\nunit_id = 1\nn = 3\nm = 3\n"
            f"[link:inst]\ntype = serial\ndevice = {link}\nbaud = 115200\n")
    d = Daemon(body, "link", state)
    p = subprocess.run([INSTR, "--link", link, "--csv", PAPER, "--model", "1"],
                       capture_output=True, text=True, timeout=120)
    check(p.returncode == 0, f"instrument upload over the link: rc {p.returncode} {p.stderr[-300:]!r}")
    st = regs(d.c.read_input_registers(0, 9, unit=1))
    d.stop()
    log = d.text()
    for want in ("link inst: CONFIGURE model 1: 3x3, flags 0", "link inst: PUT model 1:",
                 "link inst: COMMIT model 1", "model 1: solved, generation"):
        check(want in log, f"-v logs {want!r}")
    gen = (st[7] << 16) | st[8] if st else -1
    # Restart on the same state: the first line about model 1 is its
    # replayed state, never "empty".
    d = Daemon(body, "link", state)
    d.stop()
    second = d.text()[len(log):]
    lines = [ln for ln in second.splitlines() if "model 1 on unit 1" in ln]
    check(lines and f"solved, 112/112 points, generation {gen}" in lines[0] and "empty" not in second,
          f"restart: model 1 logged once as replayed ({lines[:2]}, generation {gen})")


def main():
    for part in (word_orders, default_unit, check_config, verbose_log):
        try:
            part()
        except Exception as e:  # a daemon that did not start, a timeout
            R.fail(f"{part.__name__}: {e!r}")
    R.tidy(T)
    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
