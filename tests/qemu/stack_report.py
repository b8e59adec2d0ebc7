#!/usr/bin/env python3
"""Worst-case stack per public function from GCC -fcallgraph-info=su (.ci).

usage: stack_report.py TITLE PUBLIC_LIST CI_FILE...

PUBLIC_LIST is a file with one public function name per line (the global
text symbols of the library). Each .ci file is a VCG graph: nodes carry the
static frame size ("N bytes (static)"), edges the calls. The worst case of a
function is its frame plus the deepest callee chain. Calls leaving the
library (memcpy, libgcc helpers) count as 0 and are marked '+ext'; calls
through pointers (it2n_sample's callback) are marked '+cb' (add the callback's
own stack); recursion or dynamic frames are marked and make the number a
lower bound. Exit 1 if the input cannot be parsed or no public function
has frame information (tests/lib's Report: "stack_report: FAIL: ..." on
stderr; nothing is added to the table on stdout, which `make size` shows).
"""
import os
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

NODE = re.compile(r'^node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE = re.compile(r'^edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')
FRAME = re.compile(r'\\n(\d+) bytes \(([a-z,]+)\)')


def parse(paths):
    """Return frames {(file, name): (bytes, kind)} and edges {(file, name): set(callee)}."""
    frames, edges = {}, {}
    for path in paths:
        with open(path, encoding="utf-8") as f:
            for line in f:
                m = NODE.match(line)
                if m:
                    fm = FRAME.search(m.group(2))
                    if fm:
                        frames[(path, m.group(1))] = (int(fm.group(1)), fm.group(2))
                    continue
                m = EDGE.match(line)
                if m:
                    edges.setdefault((path, m.group(1)), set()).add(m.group(2))
    return frames, edges


def main():
    if len(sys.argv) < 4:
        print(__doc__, file=sys.stderr)
        return 2
    title, public_list, cis = sys.argv[1], sys.argv[2], sys.argv[3:]
    R = report.Report("stack_report", quiet_ok=True)
    with open(public_list, encoding="utf-8") as f:
        public = sorted({l.strip() for l in f if l.strip()})
    frames, edges = parse(cis)
    if not frames:
        R.fail("no frame information in the .ci files")
        return R.finish(summary=False)
    # Resolve a callee name: same file first (static functions), else any.
    by_name = {}
    for key in frames:
        by_name.setdefault(key[1], []).append(key)

    def resolve(path, name):
        if (path, name) in frames:
            return (path, name)
        cands = by_name.get(name)
        return cands[0] if cands else None

    memo = {}

    def worst(key, stack):
        """(bytes, flags, chain) for the deepest path from key."""
        if key in memo:
            return memo[key]
        if key in stack:
            return (0, {"recursion"}, [key[1]])
        size, kind = frames[key]
        flags = set()
        if "dynamic" in kind and "bounded" not in kind:
            flags.add("dynamic")  # alloca/VLA: the frame has no static bound
        best = (0, set(), [])
        for callee in sorted(edges.get(key, ())):
            if callee == "__indirect_call":
                flags.add("cb")
                continue
            ck = resolve(key[0], callee)
            if ck is None:
                flags.add("ext")
                continue
            sub = worst(ck, stack | {key})
            flags |= sub[1]
            if sub[0] > best[0] or not best[2]:
                best = sub
        res = (size + best[0], flags, [key[1]] + best[2])
        if "recursion" not in flags:
            memo[key] = res
        return res

    rows = []
    for name in public:
        key = resolve("", name)
        if key is None:
            continue
        total, flags, chain = worst(key, frozenset())
        rows.append((name, frames[key][0], total, flags, chain))
        R.ok("%s: %d bytes" % (name, total))
    if not rows:
        R.fail("none of the %d public functions has frame info" % len(public))
        return R.finish(summary=False)
    print(f"Worst-case stack, {title} (bytes; +ext: excludes memcpy/libgcc leaf helpers,"
          " +cb: plus the callback's own stack)")
    print(f"  {'function':<26} {'frame':>6} {'worst':>6}  deepest chain")
    for name, own, total, flags, chain in sorted(rows, key=lambda r: (-r[2], r[0])):
        mark = "".join(f" +{f}" for f in sorted(flags))
        path = " > ".join(chain[:6]) + (" > ..." if len(chain) > 6 else "")
        print(f"  {name:<26} {own:>6} {total:>6}  {path}{mark}")
    deepest = max(rows, key=lambda r: r[2])
    print(f"  deepest public entry point: {deepest[0]} = {deepest[2]} bytes")
    return R.finish(summary=False)


if __name__ == "__main__":
    sys.exit(main())
