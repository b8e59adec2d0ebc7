"""Subprocesses for tests: run with a timeout, wait for a listener."""
import socket
import subprocess
import time


def run(argv, timeout=60, stdin=None, env=None, cwd=None):
    """(returncode, stdout, stderr) as text; a hang past timeout raises
    subprocess.TimeoutExpired (the test fails loudly instead of hanging)."""
    p = subprocess.run(list(argv), input=stdin, capture_output=True, text=True, timeout=timeout,
                       env=env, cwd=cwd)
    return p.returncode, p.stdout, p.stderr


def wait_port(port, proc=None, timeout=10.0, host="127.0.0.1"):
    """True once host:port accepts a connection; False after timeout or as
    soon as proc (a Popen, optional) has exited."""
    end = time.time() + timeout
    while time.time() < end:
        if proc is not None and proc.poll() is not None:
            return False
        try:
            socket.create_connection((host, port), timeout=0.5).close()
            return True
        except OSError:
            time.sleep(0.05)
    return False
