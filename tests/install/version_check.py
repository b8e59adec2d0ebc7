#!/usr/bin/python3
"""make pkg-version: one version (the file VERSION) everywhere it appears.

Compares VERSION with library.json (PlatformIO), debian/changelog, the man
pages whose footer names a version, what `it2n --version`, `it2nctl
--version` and `it2nd --version` print, the
pkg-config files the Makefile generates and the ones CMake configures
(project(VERSION) of CMakeLists.txt). Exit 1 and one line per mismatch.
usage: version_check.py [--version-file F] --build BUILD IT2N IT2NCTL IT2ND
(--version-file: compare against another file; the suite's self-test uses
one saying 9.9.9 and expects every source to disagree.)"""
import argparse
import glob
import json
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

R = report.Report("pkg-version")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--version-file", default=os.path.join(ROOT, "VERSION"))
    ap.add_argument("--build", required=True)
    ap.add_argument("programs", nargs=3)
    a = ap.parse_args()
    text = open(a.version_file).read()
    want = text.strip()
    errs = []
    if not re.fullmatch(r"[0-9]+\.[0-9]+\.[0-9]+\n", text):
        errs.append(f"{a.version_file}: not one line X.Y.Z: {text!r}")
    seen = {}
    seen["library.json"] = json.load(open(os.path.join(ROOT, "library.json"))).get("version")
    m = re.match(r"it2n \(([^)]+)\)", open(os.path.join(ROOT, "debian", "changelog")).readline())
    seen["debian/changelog"] = m.group(1) if m else None
    for prog in a.programs:
        name = os.path.basename(prog)
        out = subprocess.run([prog, "--version"], capture_output=True, text=True, timeout=30).stdout
        m = re.match(r"%s ([^\s]+)" % re.escape(name), out)
        seen[f"{name} --version"] = m.group(1) if m else out.strip()[:60]
    # man pages whose .TH footer carries a version ("it2n X.Y.Z")
    for man in sorted(glob.glob(os.path.join(ROOT, "*", "*.[18]")) + glob.glob(os.path.join(ROOT, "examples", "*", "*.[18]"))):
        m = re.match(r'\.TH \S+ \d+ "[^"]*" "it2n ([^"]+)"', open(man).readline())
        if m:
            seen[os.path.relpath(man, ROOT)] = m.group(1)
    pcs = sorted(glob.glob(os.path.join(a.build, "pkgconfig", "*.pc")))
    if not pcs:
        errs.append(f"no pkg-config files under {a.build}/pkgconfig (make generates them for install-lib)")
    for pc in pcs:
        m = re.search(r"^Version: *(\S+)", open(pc).read(), re.M)
        seen[os.path.relpath(pc, ROOT)] = m.group(1) if m else None
    with tempfile.TemporaryDirectory() as d:
        r = subprocess.run(["cmake", "-S", ROOT, "-B", d], capture_output=True, text=True, timeout=120)
        if r.returncode:
            errs.append("cmake configure failed:\n" + r.stdout[-2000:] + r.stderr[-2000:])
        else:
            for pc in sorted(glob.glob(os.path.join(d, "*.pc"))):
                m = re.search(r"^Version: *(\S+)", open(pc).read(), re.M)
                seen["CMake " + os.path.basename(pc)] = m.group(1) if m else None
            if not any(k.startswith("CMake ") for k in seen):
                errs.append("CMake configured no .pc file")
    for k, v in seen.items():
        if v != want:
            errs.append(f"{k}: {v!r}, VERSION says {want!r}")
    return R.verdict(errs, f"{want} in VERSION and {len(seen)} places: {', '.join(seen)}")


if __name__ == "__main__":
    sys.exit(main())
