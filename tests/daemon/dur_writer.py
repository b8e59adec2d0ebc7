#!/usr/bin/python3
"""Durability test client: for SECONDS, write the data point D(0,0) of unit 1
over Modbus TCP (FC 16, the upload block 40..51, T = VALUE, VALUE+1, ...)
on one connection, one write every 20 ms, and append "VALUE ok" or
"VALUE exc N" per write to OUTFILE. With --until-ok, stop at the first
write acknowledged after SECONDS (or after 10 s more)."""
import socket, struct, sys, time

port, seconds, value, out = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
until_ok = "--until-ok" in sys.argv
s = socket.create_connection(("127.0.0.1", port))
s.settimeout(5)
tid = 0

def recv(n):
    b = b""
    while len(b) < n:
        c = s.recv(n - len(b))
        if not c:
            raise OSError("closed")
        b += c
    return b

def write(t):
    global tid
    tid = (tid + 1) & 0xFFFF
    # i j fp, x -17.00 (i32), y 17.00, z 0, T I F
    regs = [0, 0, 3, 65535, 63836, 0, 1700, 0, 0, t, 7000, 2000]
    pdu = struct.pack(">BHHB", 16, 40, len(regs), 2 * len(regs)) + struct.pack(">%dH" % len(regs), *regs)
    s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu)
    hdr = recv(8)
    length = struct.unpack(">H", hdr[4:6])[0]
    body = recv(length - 2)
    if hdr[7] & 0x80:
        return "exc %d" % body[0]
    return "ok"

t0 = time.time()
with open(out, "a") as f:
    while True:
        r = write(value)
        f.write("%d %s\n" % (value, r))
        f.flush()
        value = (value + 1) % 10001
        elapsed = time.time() - t0
        if elapsed >= seconds and (not until_ok or r == "ok" or elapsed > seconds + 10):
            break
        time.sleep(0.02)
