#!/usr/bin/python3
"""No function of the front ends (cli/**/*.c) is longer than a limit.

A function is counted from the line of its name to its closing brace (a
definition starts at column 0 with a '{' line of its own or at the end of
its signature, and ends with a '}' at column 0: the project's style, which
make format-check keeps). Lines inside string literals and comments count:
they are what a reader scrolls through.

usage: fn_length.py [--max N] [--allow FILE:NAME]... FILE...
(exit 1 and one line per function over the limit; the longest few are
printed either way). --allow names a function let through for now; the
check fails when an allowed one is no longer over the limit, so the list
only shrinks.
"""
import os
import re
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

args = sys.argv[1:]
limit = 100
allowed = set()
while args[:1] in (["--max"], ["--allow"]):
    if args[0] == "--max":
        limit = int(args[1])
    else:
        allowed.add(args[1])
    args = args[2:]
if not args:
    sys.exit("usage: fn_length.py [--max N] FILE...")

# A definition's first line: not indented, not a declaration ending in ';',
# with a name followed by '('.
HEAD = re.compile(r"^[A-Za-z_][\w \t\*]*?\b([A-Za-z_]\w*)\s*\(")
found = []
for path in args:
    lines = open(path, encoding="utf-8").read().split("\n")
    i = 0
    while i < len(lines):
        m = HEAD.match(lines[i])
        if m and "=" not in lines[i][:m.end()] and not lines[i].startswith("typedef") \
                and not lines[i].rstrip().endswith(";"):
            # find the opening brace of the body before any ';'
            j = i
            while j < len(lines) and "{" not in lines[j] and not lines[j].rstrip().endswith(";"):
                j += 1
            if j < len(lines) and "{" in lines[j] and not lines[j].rstrip().endswith(";"):
                k = j + 1
                while k < len(lines) and not lines[k].startswith("}"):
                    k += 1
                found.append((k - i + 1, path, i + 1, m.group(1)))
                i = k + 1
                continue
        i += 1
found.sort(reverse=True)
over = [f for f in found if f[0] > limit and f"{f[1]}:{f[3]}" not in allowed]
problems = [f"{path}:{line}: {name} is {n} lines (at most {limit}: split it)" for n, path, line, name in over]
long_names = {f"{f[1]}:{f[3]}" for f in found if f[0] > limit}
problems += [f"--allow {a}: no such function over {limit} lines any more (drop it from the list)"
             for a in sorted(allowed - long_names)]
sys.exit(report.Report("fn_length").verdict(
    problems, f"{len(found)} functions, longest " + ", ".join(f"{name} {n}" for n, _, _, name in found[:3]) +
    f"; none over {limit} lines but the {len(allowed)} allowed"))
