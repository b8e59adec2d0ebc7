#!/usr/bin/python3
"""docs/design.md matches the tree: every path it names in backquotes
exists, and every module (.c file) of firmware_core/, protocol/, regmap/
and daemon/
is named there. A module added or renamed without its line in the design
page fails here.

usage: design_check.py [ROOT]
"""
import glob
import os
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

root = sys.argv[1] if len(sys.argv) > 1 else "."
text = open(os.path.join(root, "docs", "design.md"), encoding="utf-8").read()
fails = []
named = set(re.findall(r"`((?:firmware_core|protocol|regmap|daemon|cli|tests|docs|examples)/[^`\s]+)`", text))
for path in sorted(named):
    if not os.path.exists(os.path.join(root, path)):
        fails.append(f"docs/design.md names {path}, which does not exist")
modules = [m for d in ("firmware_core", "protocol", "regmap", "daemon")
           for m in sorted(glob.glob(os.path.join(root, d, "*.c")))]
for m in modules:
    rel = os.path.relpath(m, root)
    if rel not in named:
        fails.append(f"{rel} is not named in docs/design.md (add it to a module table)")
sys.exit(report.Report("design_check").verdict(
    fails, f"{len(named)} paths named, {len(modules)} modules, each named in docs/design.md and existing"))
