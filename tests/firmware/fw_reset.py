#!/usr/bin/python3
"""Reset the emulated board N times at random points of its boot, for
tests/firmware/fw_reboot.sh. Each boot gets a target — before its HELLO,
right after its HELLO, CONFIGURE, the k-th PUT, COMMIT, or the k-th QUERY
answer — watched in the daemon's log (what it received) and the firmware's
semihosting output (EVAL lines follow QUERY answers); the board is reset
through the qemu monitor as soon as the target is seen (the firmware runs
on meanwhile: the reset lands during that exchange or the next). Before
each reset the seed file gets the other measurement. Starts the VM (it waits
with -S). Prints the phase counts; exit 1 when a boot never reached its
target (10 s).
usage: fw_reset.py MONITOR_SOCKET DAEMON_LOG QEMU_LOG SEED_FILE N SEED0 SEED1
"""
import random
import socket
import sys
import time

mon, dlog, qlog, seedf, n, s0, s1 = sys.argv[1:8]
n = int(n)
rng = random.Random(int(time.time() * 1000) & 0xFFFFFFFF)
s = socket.socket(socket.AF_UNIX)
s.connect(mon)
s.settimeout(5)


def prompt():
    b = b""
    while not b.rstrip().endswith(b"(qemu)"):
        c = s.recv(4096)
        if not c:
            break
        b += c
    return b


def size(path):
    with open(path, "rb") as f:
        return len(f.read())


def since(path, off):
    with open(path, "rb") as f:
        f.seek(off)
        return f.read().decode("latin-1")


prompt()
# The VM waits (-S): start it here, so the first boot is watched from its start.
first = (size(dlog), size(qlog))
s.sendall(b"cont\n")
prompt()
s.sendall(b"info status\n")
if b"running" not in prompt():
    sys.exit("fw_reset: qemu did not start running")
phases = {"boot": 0, "HELLO": 0, "CONFIGURE": 0, "PUT": 0, "COMMIT": 0, "QUERY": 0}
seed = s0
gaps = []  # per boot: the daemon's HELLO answer to the boot's CONFIGURE, ms
for b in range(n):
    d0, q0 = first if b == 0 else (size(dlog), size(qlog))
    kind = rng.choice(["boot", "HELLO", "CONFIGURE", "PUT", "PUT", "PUT", "COMMIT", "QUERY", "QUERY"])
    k = rng.randint(1, 12) if kind == "PUT" else rng.randint(1, 7) if kind == "QUERY" else 1
    t0 = time.time()
    t_hello = t_cfg = None
    while True:
        d, q = since(dlog, d0), since(qlog, q0)
        if t_hello is None and "HELLO from" in d:
            t_hello = time.time()
        if t_cfg is None and "CONFIGURE model" in d:
            t_cfg = time.time()
        got = {"boot": "SEED " in q and rng.random() < 0.05,
               "HELLO": "HELLO from" in d,
               "CONFIGURE": "CONFIGURE model" in d,
               "PUT": d.count("PUT model") >= k,
               "COMMIT": "COMMIT model" in d,
               "QUERY": q.count("EVAL ") >= k}[kind]
        if got:
            break
        if time.time() - t0 > 10:
            sys.exit("fw_reset: boot %d never reached %s %d" % (b + 1, kind, k))
        time.sleep(0.002)
    # where the boot was when the reset came
    at = "boot"
    for p, key in (("HELLO", "HELLO from"), ("CONFIGURE", "CONFIGURE model"), ("PUT", "PUT model"),
                   ("COMMIT", "COMMIT model")):
        if key in d:
            at = p
    if "EVAL " in q:
        at = "QUERY"
    phases[at] += 1
    if t_hello is not None and t_cfg is not None:
        gaps.append(int((t_cfg - t_hello) * 1000))
    seed = s1 if seed == s0 else s0
    with open(seedf, "w") as f:
        f.write(seed + "\n")
    if b == n - 1:
        print("LAST_OFF %d" % size(qlog))  # the last boot's output starts here
    s.sendall(b"system_reset\n")
    prompt()
print(" ".join("%s %d," % (p, c) for p, c in phases.items()))
print("HELLO_TO_CONFIGURE_MS %d %d" % (len(gaps), max(gaps) if gaps else 0))
print("SEED_LAST %s" % seed)
sys.stdout.flush()
