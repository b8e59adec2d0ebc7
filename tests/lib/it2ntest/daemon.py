"""One it2nd process for a test: write its configuration, start it, wait
until it listens, stop it (SIGTERM, then SIGKILL), kill -9 it, read its log."""
import os
import signal
import subprocess

from . import ports
from .proc import wait_port


def basic_conf(state_dir, port, body="", daemon_extra=""):
    """A minimal configuration: state in state_dir, fsync off, Modbus TCP on
    127.0.0.1:port; daemon_extra goes into [daemon], body after [modbus]."""
    return ("[daemon]\nstate_dir = %s\nfsync = no\n%s[modbus]\ntcp_listen = 127.0.0.1:%d\n%s"
            % (state_dir, daemon_extra, port, body))


class Daemon:
    """it2nd -c CONF -f [args] with stdout and stderr appended to LOG."""

    def __init__(self, binary, conf, log, args=("-v",), env=None, port=None):
        self.binary, self.conf, self.logpath = binary, conf, log
        self.args, self.env, self.port = list(args), env, port
        self.proc = None

    def write_conf(self, text):
        with open(self.conf, "w") as f:
            f.write(text)

    def start(self, timeout=10.0, wait=True):
        """Start it; with wait, return once it accepts on self.port. Raises
        RuntimeError with the log when it exits or does not listen in time."""
        with open(self.logpath, "a") as logf:
            self.proc = subprocess.Popen([self.binary, "-c", self.conf, "-f"] + self.args, stdout=logf,
                                         stderr=subprocess.STDOUT, env=self.env)
        if wait and self.port is not None and not wait_port(self.port, self.proc, timeout):
            self.stop()
            raise RuntimeError("it2nd did not start listening on %d:\n%s" % (self.port, self.text()))
        return self

    def alive(self):
        return self.proc is not None and self.proc.poll() is None

    def stop(self, timeout=10.0, sig=signal.SIGTERM):
        """Signal it and wait; SIGKILL if it outlives timeout. Its exit status
        (None if never started)."""
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode

    def kill9(self):
        """kill -9 (a power cut as the process sees it)."""
        return self.stop(timeout=10.0, sig=signal.SIGKILL)

    def text(self):
        """The whole log so far."""
        try:
            with open(self.logpath, errors="replace") as f:
                return f.read()
        except OSError:
            return ""


def start_simple(binary, tmp, name, body="", daemon_extra="", args=("-v",), timeout=10.0):
    """A fresh it2nd in tmp/NAME.{conf,log,state} on a free port, listening."""
    port = ports.free_port()
    d = Daemon(binary, os.path.join(tmp, name + ".conf"), os.path.join(tmp, name + ".log"), args=args,
               port=port)
    d.state = os.path.join(tmp, name + ".state")
    d.write_conf(basic_conf(d.state, port, body, daemon_extra))
    return d.start(timeout=timeout)
