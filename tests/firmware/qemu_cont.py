#!/usr/bin/python3
"""Resume a qemu started with -S through its HMP monitor socket, and only
return once qemu reports the VM running ('info status').
usage: qemu_cont.py MONITOR_SOCKET"""
import socket
import sys
import time

s = socket.socket(socket.AF_UNIX)
s.connect(sys.argv[1])
s.settimeout(5)

def until_prompt():
    buf = b""
    while not buf.rstrip().endswith(b"(qemu)"):
        chunk = s.recv(4096)
        if not chunk:
            break
        buf += chunk
    return buf

until_prompt()
for _ in range(20):
    s.sendall(b"cont\n")
    until_prompt()
    s.sendall(b"info status\n")
    if b"running" in until_prompt():
        sys.exit(0)
    time.sleep(0.1)
sys.exit(1)
