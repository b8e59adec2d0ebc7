"""One it2nd process for a test: write its configuration, start it, wait
until it listens, stop it (SIGTERM, then SIGKILL), kill -9 it, read its log."""
import argparse
import os
import signal
import subprocess
import time

from . import ports
from .proc import wait_port


def basic_conf(state_dir, port, body="", daemon_extra=""):
    """A minimal configuration: state in state_dir, fsync off, Modbus TCP on
    127.0.0.1:port; daemon_extra goes into [daemon], body after [modbus]."""
    return ("[daemon]\nstate_dir = %s\nfsync = no\n%s[modbus]\ntcp_listen = 127.0.0.1:%d\n%s"
            % (state_dir, daemon_extra, port, body))


def arg_parser(*programs):
    """An ArgumentParser with a required --NAME PATH for each program
    ("it2nd", "plc", ...); parse_args() gives them as absolute paths (the
    tests start them from other directories)."""
    ap = argparse.ArgumentParser()
    for p in programs:
        ap.add_argument("--" + p, required=True, type=os.path.abspath)
    return ap


def file_sig(path):
    """(inode, size, mtime in ns) of a file, None if there is none: whether
    the daemon rewrote or replaced a state file (snapshot, wal) meanwhile."""
    try:
        st = os.stat(path)
        return (st.st_ino, st.st_size, st.st_mtime_ns)
    except FileNotFoundError:
        return None


class Daemon:
    """it2nd -c CONF -f [args] with stdout and stderr appended to the file
    log; self.proc is its Popen (kept after it exits, for the status)."""

    def __init__(self, binary, conf, log, args=("-v",), env=None, port=None, cwd=None, name="it2nd"):
        self.binary, self.conf, self.log = binary, conf, log
        self.args, self.env, self.port, self.cwd, self.name = list(args), env, port, cwd, name
        self.proc = None

    def write_conf(self, text, atomic=False):
        """The configuration file; atomic: written aside and renamed over
        it (a reload never sees it half written)."""
        path = self.conf + ".new" if atomic else self.conf
        with open(path, "w") as f:
            f.write(text)
        if atomic:
            os.replace(path, self.conf)

    def start(self, timeout=10.0, wait=True, ready=None, prefix=(), preexec_fn=None):
        """Start it (prefix: a wrapper command before the binary). With wait,
        return once it accepts on self.port or, with ready, once ready
        appears in the log it writes from now on. RuntimeError with the log
        when it exits first or is not ready in time."""
        since = len(self.text())
        with open(self.log, "a") as logf:
            self.proc = subprocess.Popen(list(prefix) + [self.binary, "-c", self.conf, "-f"] + self.args,
                                         stdout=logf, stderr=subprocess.STDOUT, env=self.env, cwd=self.cwd,
                                         preexec_fn=preexec_fn)
        if not wait:
            return self
        if ready is not None:
            end = time.time() + timeout
            while time.time() < end:
                if ready in self.text()[since:]:
                    return self
                if self.proc.poll() is not None:
                    raise RuntimeError("%s exited: %s" % (self.name, self.text()[-2000:]))
                time.sleep(0.02)
            raise RuntimeError("%s not ready: %s" % (self.name, self.text()[-2000:]))
        if self.port is not None and not wait_port(self.port, self.proc, timeout):
            exited = self.proc.poll() is not None
            self.stop()
            raise RuntimeError("%s %s: %s" % (self.name, "exited" if exited else "not listening on %d" % self.port,
                                              self.text()[-2000:]))
        return self

    def alive(self):
        return self.proc is not None and self.proc.poll() is None

    def hup(self):
        self.proc.send_signal(signal.SIGHUP)

    def hup_and_wait(self, text, timeout=5.0):
        """SIGHUP, then wait for text in the log written after it: that
        part of the log, or None when text did not come in time."""
        since = len(self.text())
        self.hup()
        if not self.wait_log(text, timeout, since):
            return None
        return self.text()[since:]

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
        """kill -9 (a power cut as the process sees it); its exit status."""
        return self.stop(timeout=10.0, sig=signal.SIGKILL)

    def text(self):
        """The whole log so far ("" before it exists)."""
        try:
            with open(self.log, errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    logtext = text

    def wait_log(self, text, timeout=5.0, since=0):
        """True once text is in the log (from character since on)."""
        end = time.time() + timeout
        while time.time() < end:
            if text in self.text()[since:]:
                return True
            time.sleep(0.02)
        return False


def start_simple(binary, tmp, name, body="", daemon_extra="", args=("-v",), timeout=10.0):
    """A fresh it2nd in tmp/NAME.{conf,log,state} on a free port, listening."""
    port = ports.free_port()
    d = Daemon(binary, os.path.join(tmp, name + ".conf"), os.path.join(tmp, name + ".log"), args=args,
               port=port)
    d.state = os.path.join(tmp, name + ".state")
    d.write_conf(basic_conf(d.state, port, body, daemon_extra))
    return d.start(timeout=timeout)
