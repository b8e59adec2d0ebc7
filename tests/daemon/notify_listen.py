#!/usr/bin/env python3
"""Bind a datagram socket as NOTIFY_SOCKET and log every sd_notify message,
one assignment per line, until killed."""
import os, socket, sys

path, log = sys.argv[1], sys.argv[2]
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(path)
with open(log, "a", buffering=1) as f:
    while True:
        data = s.recv(4096).decode()
        for line in data.split("\n"):
            f.write(line + "\n")
