"""Modbus TCP on a raw socket, for tests that must control every byte
(connection counts, pipelining, timing) where pymodbus would hide them.
A reply is the PDU (bytes), or ("exc", code) for an exception response."""
import socket
import struct


def mbap(tid, unit, pdu):
    """The MBAP header (protocol 0) and pdu: one request frame."""
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def recv_exact(s, n):
    """n bytes from s; ConnectionError if the peer closes first."""
    b = b""
    while len(b) < n:
        c = s.recv(n - len(b))
        if not c:
            raise ConnectionError("closed after %d of %d bytes" % (len(b), n))
        b += c
    return b


def request(s, unit, pdu, tid=1):
    """Send one request, return ("exc", code) or the reply PDU; ValueError
    when the reply's header does not match the request (tid, protocol, unit)."""
    s.sendall(mbap(tid, unit, pdu))
    hdr = recv_exact(s, 7)
    t, proto, length, u = struct.unpack(">HHHB", hdr)
    body = recv_exact(s, length - 1)
    if t != tid or proto != 0 or u != unit:
        raise ValueError("bad reply header %r" % hdr)
    if body[0] & 0x80:
        return ("exc", body[1])
    return body


def read_regs(s, unit, addr, count, tid=1, fc=4):
    """FC 04 (input) or, with fc=3, FC 03 (holding): a tuple of count
    registers, or ("exc", code)."""
    r = request(s, unit, struct.pack(">BHH", fc, addr, count), tid)
    if isinstance(r, tuple):
        return r
    return struct.unpack(">%dH" % count, r[2:2 + 2 * count])


def write_regs(s, unit, addr, vals, tid=1):
    """FC 16: "ok", or ("exc", code)."""
    r = request(s, unit, struct.pack(">BHHB", 16, addr, len(vals), 2 * len(vals))
                + struct.pack(">%dH" % len(vals), *vals), tid)
    return r if isinstance(r, tuple) else "ok"


def connect(port, host="127.0.0.1", src=None, timeout=3.0):
    """A TCP connection to host:port (IPv6 when host has a colon), from
    source address src if given."""
    fam = socket.AF_INET6 if ":" in host else socket.AF_INET
    s = socket.socket(fam, socket.SOCK_STREAM)
    s.settimeout(timeout)
    if src:
        s.bind((src, 0))
    s.connect((host, port))
    return s
