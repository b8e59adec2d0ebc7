#!/usr/bin/python3
"""Figures in README.md and docs/*.md that come from the build: each lives
between `<!-- fig:NAME -->` and `<!-- /fig:NAME -->` and is the verbatim
output of one command (below), in a fenced block.

usage: docfig.py --write   regenerate every block in place
       docfig.py --check   exit 1 with a diff if a committed block differs
                           (make test: a figure in the docs cannot drift)
"""
import difflib
import glob
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.environ.get("BUILD", "build")


def run(cmd):
    out = subprocess.run(cmd, shell=True, cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    if out.returncode != 0:
        sys.stderr.write(out.stdout + out.stderr)
        raise SystemExit(f"docfig.py: command failed: {cmd}")
    return out.stdout


def grep(cmd, prefix):
    return "".join(l[2:] if l.startswith("  ") else l
                   for l in run(cmd).splitlines(keepends=True) if l.lstrip().startswith(prefix))


# name -> function returning the block's text
FIGURES = {
    "make-size": lambda: run("make -s --no-print-directory size"),
    "accuracy": lambda: grep(f"{BUILD}/tests/core/test_accuracy", "[accuracy]"),
    "operations": lambda: grep(f"{BUILD}/tests/core/test_operations", "[operations]"),
}

BLOCK = re.compile(r"(<!-- fig:([a-z0-9-]+) -->\n)(.*?)(<!-- /fig:\2 -->)", re.S)


def render(name):
    if name not in FIGURES:
        raise SystemExit(f"docfig.py: unknown figure '{name}'")
    return "```\n" + FIGURES[name]().rstrip("\n") + "\n```\n"


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else "--check"
    cache, bad = {}, False
    files = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
    for path in files:
        with open(path, encoding="utf-8") as f:
            text = f.read()

        def sub(m):
            name = m.group(2)
            if name not in cache:
                cache[name] = render(name)
            return m.group(1) + cache[name] + m.group(4)

        new = BLOCK.sub(sub, text)
        if new == text:
            continue
        rel = os.path.relpath(path, ROOT)
        if mode == "--write":
            with open(path, "w", encoding="utf-8") as f:
                f.write(new)
            print(f"docfig.py: updated {rel}")
        else:
            bad = True
            sys.stdout.writelines(difflib.unified_diff(
                text.splitlines(keepends=True), new.splitlines(keepends=True),
                f"{rel} (committed)", f"{rel} (from the build)"))
    if bad:
        print("docfig.py: figures in the docs are stale: run 'make docs-figures'", file=sys.stderr)
        return 1
    print(f"docfig.py: {len(cache)} generated figure(s) current" if mode != "--write"
          else f"docfig.py: {len(cache)} figure(s) written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
