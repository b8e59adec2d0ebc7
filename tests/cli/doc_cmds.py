#!/usr/bin/env python3
"""Run the it2n command blocks of the docs as written.

Usage: doc_cmds.py BIN FILE.md|PAGE.1 ...

In Markdown, a fenced ```sh block right after a line `<!-- run: it2n -->`;
in a man page, the .nf/.fi block of .SH EXAMPLES (with \\- read as -). Each
block is run with
bash -e -o pipefail in a scratch directory that holds the repository's
examples/ (and an empty docs/img/), with BIN's directory first on PATH, so
`it2n ...` is the binary under test. Any failing command fails the test.
"""
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

BIN = os.path.abspath(sys.argv[1])
MARK = "<!-- run: it2n -->"


def man_examples(path):
    lines = open(path).read().split("\n")
    start = lines.index(".SH EXAMPLES")
    nf = lines.index(".nf", start)
    fi = lines.index(".fi", nf)
    yield nf + 2, "\n".join(ln.replace("\\-", "-")
                            for ln in lines[nf + 1:fi])


def blocks(path):
    if path.endswith(".1"):
        yield from man_examples(path)
        return
    lines = open(path).read().split("\n")
    for k, ln in enumerate(lines):
        if ln.strip() != MARK:
            continue
        if k + 1 >= len(lines) or not re.match(r"^\s*```(sh|bash)\s*$",
                                               lines[k + 1]):
            yield k + 1, None
            continue
        end = next(e for e in range(k + 2, len(lines))
                   if lines[e].strip() == "```")
        yield k + 2, "\n".join(lines[k + 2:end])


def main():
    root = os.getcwd()
    env = dict(os.environ, PATH=os.path.dirname(BIN) + os.pathsep +
               os.environ.get("PATH", ""))
    R = report.Report("cli-docs")
    for path in sys.argv[2:]:
        for line, text in blocks(path):
            if text is None:
                R.fail(f"{path}:{line}: {MARK} not followed by a ```sh block")
                continue
            with tempfile.TemporaryDirectory() as tmp:
                os.symlink(os.path.join(root, "examples"),
                           os.path.join(tmp, "examples"))
                os.makedirs(os.path.join(tmp, "docs", "img"))
                p = subprocess.run(["bash", "-e", "-o", "pipefail", "-c",
                                    "type -P it2n >&2\n" + text],
                                   cwd=tmp, env=env, capture_output=True,
                                   text=True, timeout=300)
                which = p.stderr.split("\n")[0]
                R.check(p.returncode == 0 and which == BIN, f"{path}:{line}: command block ran",
                        f"exits {p.returncode} (it2n is {which})\n{p.stderr}")
    return R.finish()  # no marked block at all: no check ran, a failure


if __name__ == "__main__":
    sys.exit(main())
