"""mosquitto for tests: a configuration written to a directory, started,
waited for on its listeners, stopped."""
import os
import shutil
import signal
import subprocess
import time

from .proc import wait_port

MOSQUITTO = shutil.which("mosquitto") or ("/usr/sbin/mosquitto" if os.path.exists("/usr/sbin/mosquitto") else None)


class Broker:
    """mosquitto -c D/mosquitto.conf, output appended to D/mosquitto.log.
    conf is the configuration text; start() waits until every port of
    wait_ports (default: port) accepts."""

    def __init__(self, d, port, conf, wait_ports=None, binary=None):
        self.port = port
        self.conf = os.path.join(d, "mosquitto.conf")
        self.log = os.path.join(d, "mosquitto.log")
        self.wait_ports = list(wait_ports) if wait_ports is not None else [port]
        self.binary = binary or MOSQUITTO
        with open(self.conf, "w") as f:
            f.write(conf)
        self.p = None

    def start(self, timeout=5.0):
        """Start it; the time.monotonic() at which it accepted on every
        listener. RuntimeError naming the log if it did not in time."""
        with open(self.log, "a") as logf:
            self.p = subprocess.Popen([self.binary, "-c", self.conf], stdout=logf, stderr=subprocess.STDOUT)
        end = time.monotonic() + timeout
        for port in self.wait_ports:
            if not wait_port(port, self.p, max(0.0, end - time.monotonic())):
                raise RuntimeError("mosquitto did not start (see %s)" % self.log)
        return time.monotonic()

    def stop(self, timeout=5.0):
        """SIGCONT (a test may have stopped it), SIGTERM, wait."""
        if self.p and self.p.poll() is None:
            self.p.send_signal(signal.SIGCONT)
            self.p.terminate()
            self.p.wait(timeout)
        self.p = None
