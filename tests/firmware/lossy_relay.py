#!/usr/bin/python3
"""Byte-dropping relay between qemu's UART pty and a new pty for it2nd.
Each byte, in either direction, is dropped with probability DROP/1000000
(seeded, reproducible). Writes the new pty's path to OUTFILE.
usage: lossy_relay.py QEMU_PTY OUTFILE DROP_PPM SEED"""
import os
import random
import select
import sys
import tty

qpty, outfile, drop, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
rng = random.Random(seed)
q = os.open(qpty, os.O_RDWR | os.O_NOCTTY)
tty.setraw(q)
master, slave = os.openpty()
tty.setraw(slave)          # it2nd sets its own mode; the slave fd stays open
with open(outfile + ".tmp", "w") as f:
    f.write(os.ttyname(slave) + "\n")
os.rename(outfile + ".tmp", outfile)
dropped = {q: 0, master: 0}
passed = {q: 0, master: 0}
peer = {q: master, master: q}
while True:
    r, _, _ = select.select([q, master], [], [])
    for fd in r:
        try:
            data = os.read(fd, 4096)
        except OSError:
            continue
        if not data:
            continue
        keep = bytes(b for b in data if rng.randrange(1000000) >= drop)
        dropped[fd] += len(data) - len(keep)
        passed[fd] += len(keep)
        if keep:
            os.write(peer[fd], keep)
        print("relay: fw->daemon passed %d dropped %d; daemon->fw passed %d dropped %d"
              % (passed[q], dropped[q], passed[master], dropped[master]), flush=True)
