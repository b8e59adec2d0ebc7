#!/usr/bin/python3
"""Every command and code snippet of README.md and docs/*.md, run as written.

usage: snippets.py [--list] [FILE.md ...]     (default: README.md docs/*.md)
environment: BUILD (default build): the built tree (build/host/it2n, it2nd,
             libit2n.a, libit2n_proto.a)

The marking rule (docs/README "Documentation checks" repeats it):

* Every fenced block whose info string is `sh`, `bash`, `c` or `python` is
  checked; other fences (plain, `ini`, `make`, `cmake`, `text`) are not code
  this script runs.
* The line right above the fence may carry a marker:
    <!-- snippet: skip REASON -->  not run; REASON (required) says why, e.g.
                                   needs root, hardware or a cross SDK.
    <!-- snippet: daemon -->       run while a fresh it2nd on its built-in
                                   default (paper model on unit 1) listens on
                                   a free loopback port; every `1502` in the
                                   block is replaced by that port.
    <!-- snippet: session -->      as daemon, but the blocks of one file so
                                   marked share one it2nd and one scratch
                                   directory, run in the order written: a
                                   reader following the page top to bottom
                                   (what one block changes, the next sees;
                                   it2nctl reaches it through IT2NCTL_TCP).
    <!-- snippet: config -->       (c) a configuration header: compiled as
                                   -DIT2N_CONFIG=<it> with it2n.h and the core.
    <!-- snippet: output -->       (any fence) the exact stdout of the checked
                                   block just before it.
    <!-- run: it2n -->             same as no marker (the CLI's own marker).
    <!-- run: TOOL -->             (another TOOL, e.g. it2nctl) run by that
                                   tool's own documentation test, which
                                   needs its own set-up (a daemon on 1502);
                                   listed here as delegated.
    <!-- file:PATH -->             a quote of PATH: must equal the file.
* Without a marker: sh/bash runs with `bash -e -o pipefail` in a scratch
  directory holding the repository's examples/ (and an empty docs/img/), with
  $BUILD/host first on PATH; python runs with /usr/bin/python3 there; a C
  block with a main() is compiled with -Wall -Wextra -Werror against
  libit2n.a (and libit2n_proto.a), run, and must exit 0; any other C block
  must compile as a translation unit.
* Every `make TARGET` a document names (in a code span or a sh block), and
  every `name` in a table column headed "make ...", must be listed by
  `make help`.
A block that fails prints FILE:LINE, the command's output and exit status.
"""
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import daemon as it2nd_proc  # noqa: E402  (local names "daemon" below are processes)
from it2ntest import report  # noqa: E402
from it2ntest.ports import free_port  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.path.join(ROOT, os.environ.get("BUILD", "build"))
HOST = os.path.join(BUILD, "host")
CHECKED = {"sh", "bash", "c", "python"}
FENCE = re.compile(r"^(\s*)```\s*([\w+-]*)\s*$")
MARK = re.compile(r"^\s*<!--\s*(.*?)\s*-->\s*$")
TIMEOUT = 120


class Block:
    def __init__(self, path, line, lang, text, marker):
        self.path, self.line, self.lang = path, line, lang
        self.text, self.marker = text, marker
        self.output = None          # expected stdout (a following output block)

    def where(self):
        return f"{os.path.relpath(self.path, ROOT)}:{self.line}"


def parse(path):
    lines = open(path, encoding="utf-8").read().split("\n")
    blocks, k = [], 0
    while k < len(lines):
        m = FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        indent, lang = m.group(1), m.group(2).lower()
        end = k + 1
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        body = [ln[len(indent):] if ln.startswith(indent) else ln.lstrip()
                for ln in lines[k + 1:end]]
        mk = MARK.match(lines[k - 1]) if k > 0 else None
        blocks.append(Block(path, k + 1, lang, "\n".join(body) + "\n",
                            mk.group(1) if mk else ""))
        k = end + 1
    # attach output blocks to the block before them
    out = []
    for b in blocks:
        if b.marker == "snippet: output":
            if not out or out[-1].lang not in CHECKED:
                raise SystemExit(f"{b.where()}: output block without a "
                                 "checked block before it")
            out[-1].output = b.text
            continue
        out.append(b)
    return out


class Daemon(it2nd_proc.Daemon):
    """A fresh it2nd with the built-in default model on a free port."""

    def __init__(self, tmp):
        super().__init__(os.path.join(HOST, "it2nd"), os.path.join(tmp, "it2nd-snippet.conf"),
                         os.path.join(tmp, "it2nd.log"), args=(), port=free_port())
        self.write_conf(it2nd_proc.basic_conf(f"{tmp}/state", self.port))
        self.start()


def scratch():
    tmp = tempfile.mkdtemp(prefix="it2n-snippet.")
    os.symlink(os.path.join(ROOT, "examples"), os.path.join(tmp, "examples"))
    os.makedirs(os.path.join(tmp, "docs", "img"))
    return tmp


def env():
    e = dict(os.environ)
    e["PATH"] = HOST + os.pathsep + e.get("PATH", "")
    e["IT2N_SRC"] = ROOT
    return e


def run(cmd, cwd, stdin=None, extra_env=None):
    e = env()
    e.update(extra_env or {})
    return subprocess.run(cmd, cwd=cwd, env=e, input=stdin,
                          capture_output=True, text=True, timeout=TIMEOUT)


class Session:
    """One it2nd and one scratch directory for a file's session blocks."""

    def __init__(self):
        self.tmp = scratch()
        self.daemon = Daemon(self.tmp)

    def close(self):
        self.daemon.stop()
        shutil.rmtree(self.tmp, ignore_errors=True)


def compile_c(b, tmp):
    src = os.path.join(tmp, "snippet.c")
    inc = ["-I" + os.path.join(ROOT, d) for d in ("firmware_core", "protocol")]
    flags = ["gcc", "-std=c11", "-D_GNU_SOURCE", "-Wall", "-Wextra",
             "-Wpedantic", "-Werror"] + inc
    if b.marker == "snippet: config":
        hdr = os.path.join(tmp, "snippet_config.h")
        open(hdr, "w").write(b.text)
        open(src, "w").write('#include "it2n.h"\nit2n_model snippet_model;\n')
        core = sorted(glob.glob(os.path.join(ROOT, "firmware_core", "*.c")))
        return _compile_core(flags, hdr, src, core, tmp)
    open(src, "w").write(b.text)
    if not re.search(r"\bmain\s*\(", b.text):
        return run(flags + ["-c", src, "-o", os.path.join(tmp, "snippet.o")],
                   tmp)
    exe = os.path.join(tmp, "snippet")
    p = run(flags + [src, "-o", exe, os.path.join(HOST, "libit2n_proto.a"),
                     os.path.join(HOST, "libit2n.a")], tmp)
    if p.returncode != 0:
        return p
    return run([exe], tmp)


def _compile_core(flags, hdr, src, core, tmp):
    """The whole core built with the configuration header: the options must
    be accepted by every file, and the struct sizes must follow them."""
    for c in [src] + core:
        p = run(flags + ["-std=c99", "-DIT2N_CONFIG=" + hdr, "-c", c, "-o",
                         os.path.join(tmp, os.path.basename(c) + ".o")], tmp)
        if p.returncode != 0:
            return p
    return p


def check_block(b, daemon, session=None):
    tmp = session.tmp if session else scratch()
    extra_env = None
    try:
        text = b.text
        if b.marker == "snippet: daemon":
            daemon = Daemon(tmp)
        if session:
            daemon = session.daemon
            extra_env = {"IT2NCTL_TCP": f"127.0.0.1:{daemon.port}"}
        if daemon:
            text = text.replace("1502", str(daemon.port))
        try:
            if b.lang in ("sh", "bash"):
                p = run(["bash", "-e", "-o", "pipefail", "-c", text], tmp,
                        extra_env=extra_env)
            elif b.lang == "python":
                p = run(["/usr/bin/python3", "-"], tmp, stdin=text,
                        extra_env=extra_env)
            else:
                p = compile_c(b, tmp)
        finally:
            if daemon and not session:
                daemon.stop()
        msg = None
        if p.returncode != 0:
            msg = f"exit status {p.returncode}"
        elif b.output is not None and p.stdout != b.output:
            msg = (f"stdout differs from the output block after it\n"
                   f"--- expected\n{b.output}--- got\n{p.stdout}")
        if msg:
            extra = ("\n--- it2nd log\n" + daemon.text()) if daemon else ""
            return (f"{msg}\n--- stdout\n{p.stdout}--- stderr\n{p.stderr}"
                    f"{extra}")
        return None
    except subprocess.TimeoutExpired:
        return f"timed out after {TIMEOUT} s"
    except RuntimeError as e:
        return str(e)
    finally:
        if not session:
            shutil.rmtree(tmp, ignore_errors=True)


def help_targets():
    # A fresh make: not the one running us (its command-line variables,
    # e.g. TEST_TARGETS=..., would change what help lists).
    e = {k: v for k, v in os.environ.items()
         if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES")}
    p = subprocess.run(["make", "-s", "--no-print-directory", "help"],
                       cwd=ROOT, capture_output=True, text=True, env=e)
    names = set()
    for ln in p.stdout.splitlines():
        names.update(w.rstrip(":,") for w in ln.split())
    return names


MAKE_SPAN = re.compile(r"`make\s+((?:-\S+\s+|[A-Z_]+=\S*\s+)*)([a-z][\w./-]*)")
MAKE_LINE = re.compile(r"^\s*make\s+((?:-\S+\s+|[A-Z_]+=\S*\s+)*)"
                       r"([a-z][\w./-]*(?:\s+[a-z][\w./-]*)*)")


def make_names(path, blocks):
    """(line, target) for every `make TARGET` the document names."""
    text = open(path, encoding="utf-8").read()
    code = {b.line + k for b in blocks if b.lang in ("sh", "bash")
            for k in range(1, b.text.count("\n") + 1)}
    found = []
    for n, ln in enumerate(text.split("\n"), 1):
        if n in code:
            m = MAKE_LINE.match(ln)
            if m:
                found += [(n, t) for t in m.group(2).split()
                          if "/" not in t]   # a file target (build/...) is no target name
        else:
            found += [(n, m.group(2)) for m in MAKE_SPAN.finditer(ln)
                      if "/" not in m.group(2)]
    return found


def table_targets(path):
    """(line, name) for every `name` in a table column headed `make ...`
    (e.g. "make test target")."""
    found, col = [], None
    for n, ln in enumerate(open(path, encoding="utf-8").read().split("\n"), 1):
        if not ln.startswith("|"):
            col = None
            continue
        cells = [c.strip() for c in ln.strip().strip("|").split("|")]
        if col is None:
            col = next((k for k, c in enumerate(cells)
                        if c.lower().startswith("make ")), -1)
            continue
        if 0 <= col < len(cells) and not set(cells[col]) <= set("-: "):
            found += [(n, t) for t in re.findall(r"`([a-z][\w-]*)`", cells[col])]
    return found


def main(argv):
    listing = "--list" in argv
    files = [a for a in argv if not a.startswith("--")] or \
        [os.path.join(ROOT, "README.md")] + \
        sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
    failures, counts = [], {"run": 0, "skip": 0, "quote": 0, "delegated": 0}
    targets = help_targets()
    for path in files:
        blocks = parse(path)
        session = None
        for line, t in make_names(path, blocks) + table_targets(path):
            if t not in targets:
                failures.append(f"{os.path.relpath(path, ROOT)}:{line}: "
                                f"`make {t}`: not listed by `make help`")
        for b in blocks:
            if b.marker.startswith("file:"):
                want = open(os.path.join(ROOT, b.marker[5:])).read()
                counts["quote"] += 1
                if b.text != want:
                    failures.append(f"{b.where()}: quote differs from "
                                    f"{b.marker[5:]}")
                continue
            if b.lang not in CHECKED:
                continue
            if b.marker.startswith("run: ") and b.marker != "run: it2n":
                counts["delegated"] += 1
                if listing:
                    print(f"{b.where()}: {b.lang}: delegated ({b.marker})")
                continue
            if b.marker.startswith("snippet: skip"):
                if not b.marker[len("snippet: skip"):].strip():
                    failures.append(f"{b.where()}: skip without a reason")
                counts["skip"] += 1
                if listing:
                    print(f"{b.where()}: {b.lang}: {b.marker}")
                continue
            if b.marker not in ("", "run: it2n", "snippet: daemon",
                                "snippet: session", "snippet: config"):
                failures.append(f"{b.where()}: unknown marker "
                                f"<!-- {b.marker} -->")
                continue
            if b.marker == "snippet: config" and b.lang != "c":
                failures.append(f"{b.where()}: config marker on a "
                                f"{b.lang} block")
                continue
            counts["run"] += 1
            if listing:
                print(f"{b.where()}: {b.lang}: {b.marker or 'default'}")
                continue
            if b.marker == "snippet: session" and session is None:
                try:
                    session = Session()
                except RuntimeError as e:
                    failures.append(f"{b.where()}: session: {e}")
                    break
            err = check_block(b, None, session if b.marker == "snippet: session" else None)
            if err:
                failures.append(f"{b.where()}: {b.lang} block: {err}")
        if session:
            session.close()
    if not counts["run"] and not listing:
        failures.append("no block checked")
    return report.Report("docs-snippets").verdict(
        failures, f"{counts['run']} checked, {counts['quote']} quotes, {counts['delegated']} run by their tool's "
        f"test, {counts['skip']} not run (marked, with reasons) in {len(files)} files")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
