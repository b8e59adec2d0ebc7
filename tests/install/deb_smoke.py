#!/usr/bin/python3
"""make deb-smoke: debian/ agrees with the tree, without building a package.

usage: deb_smoke.py STAGED_ROOT UNITDIR
STAGED_ROOT is `make install DESTDIR=STAGED_ROOT PREFIX=/usr
LIBDIR=/usr/lib/TRIPLET UNITDIR=UNITDIR`, what debian/rules installs into
debian/tmp. Checks, as dh_install and dh_missing will:
  - every pattern of debian/it2n.install and debian/libit2n-dev.install
    (and UNITDIR, which debian/rules adds to it2n) matches something;
  - every staged file goes to exactly one package;
  - libit2n-dev gets the libraries, headers and pkg-config files only;
and that debian/changelog's version is the file VERSION's.
"""
import glob
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

R = report.Report("deb-smoke")


def main():
    root, unitdir = sys.argv[1], sys.argv[2]
    errors = []
    ver = subprocess.run(["dpkg-parsechangelog", "-l", "debian/changelog", "-S", "Version"],
                         capture_output=True, text=True, check=True).stdout.strip()
    cli = open("VERSION").read().strip()
    if ver != cli:
        errors.append(f"debian/changelog version {ver} is not VERSION's {cli} (dch -v {cli})")
    staged = set()
    for d, _, fs in os.walk(root):
        for f in fs:
            staged.add(os.path.relpath(os.path.join(d, f), root))
    owner = {}
    for pkg in ("it2n", "libit2n-dev"):
        pats = [l.split()[0] for l in open(f"debian/{pkg}.install") if l.strip() and not l.startswith("#")]
        if pkg == "it2n":
            pats.append(unitdir.lstrip("/"))
        for pat in pats:
            hits = glob.glob(os.path.join(root, pat.rstrip("/")))
            if not hits:
                errors.append(f"debian/{pkg}.install: {pat} matches nothing (dh_install fails)")
            for h in hits:
                rel = os.path.relpath(h, root)
                got = [s for s in staged if s == rel or s.startswith(rel + "/")]
                for s in got:
                    owner.setdefault(s, set()).add(pkg)
    for s in sorted(staged):
        if s not in owner:
            errors.append(f"{s}: in no package (dh_missing fails)")
        elif len(owner[s]) > 1:
            errors.append(f"{s}: in {sorted(owner[s])}")
    dev_ok = re.compile(r"^usr/(include/it2n/[^/]+\.h|lib/[^/]+/(lib[a-z0-9_]+\.a|pkgconfig/[a-z0-9-]+\.pc))$")
    for s, p in owner.items():
        if "libit2n-dev" in p and not dev_ok.match(s):
            errors.append(f"libit2n-dev would get {s}")
    n = {p: sum(1 for s in owner.values() if p in s) for p in ("it2n", "libit2n-dev")}
    sys.exit(R.verdict(errors, f"debian/ version {ver} = VERSION; make install PREFIX=/usr: {len(staged)} files, "
                       f"{n['it2n']} to it2n, {n['libit2n-dev']} to libit2n-dev, none left out or twice"))


if __name__ == "__main__":
    main()
