"""Free loopback TCP ports for test listeners.

Why not bind port 0: the kernel then hands out a port from its ephemeral
range, and between our close() and the daemon's bind() an outgoing connection
(another suite's client, a broker connection) can take that very port, so the
daemon fails to listen. Ports are picked at random below the ephemeral range
instead, and never twice in one run (a daemon that is restarted later must
not find its port handed to another one meanwhile).
"""
import random
import socket

_given = set()


def ephemeral_low():
    """First port of the kernel's ephemeral range (32768 if unknown)."""
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port(host="127.0.0.1", avoid=()):
    """A port on host that nothing listens on now, below the ephemeral range,
    not returned before in this process nor in avoid (ports a shell script
    already holds: each of its calls is a new process)."""
    lo = ephemeral_low()
    for _ in range(1000):
        p = random.randrange(max(1024, lo - 12000), lo)
        if p in _given or p in avoid:
            continue
        s = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
        try:
            s.bind((host, p))
        except OSError:
            continue
        finally:
            s.close()
        _given.add(p)
        return p
    raise RuntimeError("no free port below %d on %s" % (lo, host))


if __name__ == "__main__":
    # testlib.sh: free_port.py [USED...] prints one port not in USED.
    import sys
    print(free_port(avoid={int(a) for a in sys.argv[1:]}))
