#!/usr/bin/python3
"""The layers hold: nothing outside the daemon reaches into daemon/.

Fails (exit 1, one line per finding) when a C file outside daemon/ and the
daemon's own test areas includes a header of daemon/ (by path, or by name
when the file's own directory and the libraries it may use hold no header
of that name), or when a build file outside them passes daemon/ as an
include directory (-Idaemon, $(DAEMON_CFLAGS), CMake include_directories).
The daemon's unit tests and fuzzers (tests/daemon/, tests/fuzz_daemon/)
test daemon modules and may include them; everything else reaches what it
shares with the daemon through a library (firmware_core/, protocol/,
regmap/).

With --make TARGETS it also asks make what it would run for those
programs (make -n -B, nothing is built) and fails on any compile line of a
source outside the daemon's areas that carries -Idaemon: a client built
with the daemon's flags from inside a daemon fragment is caught too.

usage: layers.py [--make "TARGET ..."] [ROOT]
"""
import glob
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

args = sys.argv[1:]
make_targets = []
if len(args) >= 2 and args[0] == "--make":
    make_targets = args[1].split()
    args = args[2:]
root = os.path.abspath(args[0] if args else ".")
# Areas that belong to the daemon: its sources, its unit tests, its fuzzers.
DAEMON_AREAS = ("daemon/", "tests/daemon/", "tests/fuzz_daemon/")
LIB_DIRS = ("firmware_core", "protocol", "regmap", "cli")


def tracked():
    """Files git tracks (and untracked ones it does not ignore); every file
    below root outside a git checkout."""
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "-co", "--exclude-standard"],
                             capture_output=True, text=True, check=True).stdout
        return [f for f in out.splitlines() if os.path.isfile(os.path.join(root, f))]
    except (OSError, subprocess.CalledProcessError):
        return [os.path.relpath(os.path.join(d, f), root)
                for d, _, fs in os.walk(root) for f in fs]


def own(path):
    return path.startswith(DAEMON_AREAS)


files = tracked()
daemon_hdrs = {os.path.basename(h) for h in glob.glob(os.path.join(root, "daemon", "*.h"))}
lib_hdrs = {os.path.basename(h) for d in LIB_DIRS for h in glob.glob(os.path.join(root, d, "*.h"))}
fails = []

inc_re = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]')
for f in files:
    if own(f) or not f.endswith((".c", ".h", ".inc", ".cc", ".cpp")):
        continue
    here = {os.path.basename(h) for h in glob.glob(os.path.join(root, os.path.dirname(f), "*.h"))}
    with open(os.path.join(root, f), encoding="utf-8", errors="replace") as fh:
        for n, line in enumerate(fh, 1):
            m = inc_re.match(line)
            if not m:
                continue
            name = m.group(1)
            base = os.path.basename(name)
            if "daemon/" in name.replace("\\", "/") and not name.startswith(("build", "$")):
                fails.append(f"{f}:{n}: includes {name}, a header of daemon/")
            elif "/" not in name and base in daemon_hdrs and base not in here and base not in lib_hdrs:
                fails.append(f"{f}:{n}: includes {name}, which only daemon/ holds")

build_re = re.compile(r"(-I\s*(\./)?daemon\b(?!/)|\$\(DAEMON_CFLAGS\)|include_directories\([^)]*\bdaemon\b)")
for f in files:
    b = os.path.basename(f)
    if own(f) or not (b.endswith((".mk", ".cmake", ".sh")) or b in ("Makefile", "CMakeLists.txt")):
        continue
    with open(os.path.join(root, f), encoding="utf-8", errors="replace") as fh:
        for n, line in enumerate(fh, 1):
            code = line.split("#", 1)[0] if not b.endswith(".sh") else line
            m = build_re.search(code)
            if m:
                fails.append(f"{f}:{n}: passes daemon/ as an include directory ({m.group(1).strip()})")

if make_targets:
    out = subprocess.run(["make", "-n", "-B", "--no-print-directory"] + make_targets, cwd=root,
                         capture_output=True, text=True)
    if out.returncode != 0:
        fails.append(f"make -n {' '.join(make_targets)} failed: {out.stderr.strip()[-300:]}")
    idaemon = re.compile(r"(^|\s)-I\s*(\./)?daemon/?(\s|$)")
    for line in out.stdout.splitlines():
        if not idaemon.search(line):
            continue
        srcs = [w for w in line.split() if w.endswith(".c")]
        # the daemon's own sources, and the code generated from them in the
        # build directory (BUILD/daemon/spb.pb-c.c, BUILD/daemon/paper_data.c)
        alien = [w for w in srcs if not w.startswith(DAEMON_AREAS) and not re.match(r"^[^/]+/daemon/", w)]
        if alien:
            fails.append(f"make compiles {' '.join(alien)} with -Idaemon")

sys.exit(report.Report("layers").verdict(fails, f"{len(files)} files, none reaches into daemon/ from outside"))
