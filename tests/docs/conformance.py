#!/usr/bin/python3
"""docs/protocol.md section 9 (conformance table) must not drift: every row
names at least one test, every test it names exists and is run by make
test, and every question id of section 4.4 (Q1..) has a row.

A test is `path:name`: in a cmocka file a function registered with
cmocka_unit_test*; in tests/protocol/daemon_link.c a mode (strcmp'd in its
main) that tests/protocol/protocol.mk runs in proto-daemon; elsewhere a
function defined in the file. `make X`: X is in some TEST_TARGETS.
usage: conformance.py [protocol.md]"""
import glob
import os
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def rd(p):
    with open(os.path.join(ROOT, p)) as f:
        return f.read()


def test_targets():
    t = set()
    for mk in glob.glob(os.path.join(ROOT, "**", "*.mk"), recursive=True) + [os.path.join(ROOT, "Makefile")]:
        if "/build/" in mk:
            continue
        for line in open(mk):
            m = re.match(r"\s*TEST_TARGETS\s*\+?=(.*)", line)
            if m:
                t.update(m.group(1).split())
    return t


def dl_modes_run():
    mk = rd("tests/protocol/protocol.mk")
    words = set()
    for line in mk.splitlines():
        if "$(PROTO_DL)" in line and "proto-daemon-long" not in line or line.startswith("PROTO_DL_ARGS"):
            words.update(re.findall(r"[a-z][a-z0-9]*", line.split("$(PROTO_DL)")[-1] if "$(PROTO_DL)" in line
                                    else line.split("=", 1)[1]))
    return words


def check(test, targets, modes):
    if test.startswith("make "):
        t = test[5:]
        return None if t in targets else "make %s is not in TEST_TARGETS (not run by make test)" % t
    if ":" not in test:
        return "not file:name or make TARGET"
    path, name = test.rsplit(":", 1)
    if not os.path.isfile(os.path.join(ROOT, path)):
        return "no file %s" % path
    src = rd(path)
    if path.endswith("daemon_link.c"):
        if 'strcmp(argv[k], "%s")' % name not in src:
            return "daemon_link has no mode %s" % name
        if name not in modes:
            return "proto-daemon does not run daemon_link mode %s" % name
        return None
    if not re.search(r"\b%s\s*\(" % re.escape(name), src):
        return "no function %s in %s" % (name, path)
    if "cmocka" in src and not re.search(r"cmocka_unit_test\w*\(\s*%s\b" % re.escape(name), src):
        return "%s is not registered with cmocka in %s" % (name, path)
    return None


def main():
    doc = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "protocol.md")
    text = open(doc).read()
    if "<!-- conformance table: tests/docs/conformance.py -->" not in text:
        print("conformance: %s has no conformance table" % doc)
        return 1
    body = text.split("<!-- conformance table: tests/docs/conformance.py -->", 1)[1]
    rows = []
    for line in body.lstrip("\n").splitlines():
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[0] != "id" and not cells[0].startswith("-"):
            rows.append(cells)
    targets, modes = test_targets(), dl_modes_run()
    errors, ids, ntests = [], set(), 0
    for cells in rows:
        if len(cells) != 4:
            errors.append("row %r: want 4 cells" % cells)
            continue
        rid, tests = cells[0], re.findall(r"`([^`]+)`", cells[3])
        if rid in ids:
            errors.append("%s: id twice" % rid)
        ids.add(rid)
        if not tests:
            errors.append("%s: names no test" % rid)
        for t in tests:
            ntests += 1
            e = check(t, targets, modes)
            if e:
                errors.append("%s: %s: %s" % (rid, t, e))
    sec44 = text.split("### 4.4", 1)[1].split("\n## ", 1)[0] if "### 4.4" in text else ""
    for q in sorted(set(re.findall(r"^\| (Q\d+) \|", sec44, re.M)), key=lambda x: int(x[1:])):
        if q not in ids:
            errors.append("%s (section 4.4) has no row in the conformance table" % q)
    return report.Report("conformance").verdict(
        errors, "%d rules, %d test references, all exist and run in make test" % (len(rows), ntests))


if __name__ == "__main__":
    sys.exit(main())
