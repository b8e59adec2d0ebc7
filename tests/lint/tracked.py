#!/usr/bin/python3
"""No generated file is tracked by git (issue 19: a libFuzzer log,
fuzz-0.log, and a __pycache__/*.pyc were committed by mistake).

Generated, by name: Python bytecode (*.pyc, *.pyo, __pycache__/), logs
(*.log), build outputs (*.o, *.a, *.so, *.elf, *.su, *.ci, *.gcda, *.gcno,
anything under build/ or state/ at the top), libFuzzer's artefacts
(crash-*, leak-*, timeout-*, oom-*, slow-unit-*) and core dumps (core,
core.PID). What the project generates on purpose and keeps (golden vectors
*.hex, docs/img/*.png, bench/*.json) is not matched: those are regenerated
and checked by their own suites.

usage: tracked.py [DIR]     the git checkout at DIR (default: this tree)
       tracked.py --selftest
Exit 1 naming each tracked generated file; --selftest shows, on a scratch
repository, that the check fails when such a file is tracked and passes
when none is.
"""
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

# (pattern on the path git reports, what it is)
GENERATED = [
    (r"(^|/)__pycache__/|\.py[co]$", "Python bytecode"),
    (r"\.log$", "a log"),
    (r"\.(o|a|so|elf|su|ci|gcda|gcno)$", "a build output"),
    (r"^(build|state)/", "a build output (build/, state/)"),
    (r"(^|/)(crash|leak|timeout|oom|slow-unit)-[^/]*$", "a libFuzzer artefact"),
    (r"(^|/)core(\.\d+)?$", "a core dump"),
]
PATTERNS = [(re.compile(p), what) for p, what in GENERATED]


def generated(path):
    """What path is when it is a generated file, else None."""
    for rx, what in PATTERNS:
        if rx.search(path):
            return what
    return None


def tracked_generated(top):
    """[(path, what)] of the files git tracks in top that are generated."""
    out = subprocess.run(["git", "-C", top, "ls-files", "-z"], check=True, capture_output=True).stdout
    paths = [p.decode("utf-8", "replace") for p in out.split(b"\0") if p]
    return [(p, generated(p)) for p in paths if generated(p)], len(paths)


def problems_of(top):
    found, count = tracked_generated(top)
    return ["%s is tracked by git but is %s: git rm --cached it (and keep it ignored, .gitignore)" % (p, what)
            for p, what in found], count


def selftest():
    R = report.Report("tracked --selftest")
    try:
        subprocess.run(["git", "--version"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError):
        R.skip("git is missing")
        return R.finish()
    with tempfile.TemporaryDirectory(prefix="it2n-tracked-") as tmp:
        def git(*a):
            subprocess.run(["git", "-C", tmp] + list(a), check=True, capture_output=True)
        git("init", "-q")
        bad = ["fuzz-0.log", "tests/cli/__pycache__/x.cpython-311.pyc", "tests/fuzz/crash-1a2b", "leak-99",
               "timeout-3", "build/host/it2n", "cli/common/opt.o", "core"]
        good = ["README.md", "protocol/vectors/00_hello.hex", "tests/cli/corpus/crash_free.csv",
                "tests/lint/tracked.py", "docs/img/paper_T.png", "cli/common/log.c", "tests/timeout.sh"]
        for p in bad + good:
            os.makedirs(os.path.join(tmp, os.path.dirname(p)), exist_ok=True)
            open(os.path.join(tmp, p), "w").close()
        git("add", "-f", "--", *good)
        probs, n = problems_of(tmp)
        R.check(not probs and n == len(good), "passes on a tree of %d source and kept files" % len(good), probs)
        git("add", "-f", "--", *bad)
        probs, n = problems_of(tmp)
        named = sorted(p.split(" is tracked")[0] for p in probs)
        R.check(named == sorted(bad), "fails naming each of the %d generated files once they are tracked" % len(bad),
                "named %s" % named)
    return R.finish()


def main():
    if sys.argv[1:] == ["--selftest"]:
        return selftest()
    top = sys.argv[1] if len(sys.argv) > 1 else "."
    R = report.Report("tracked")
    try:
        inside = subprocess.run(["git", "-C", top, "rev-parse", "--is-inside-work-tree"], capture_output=True)
    except OSError:
        inside = None
    if inside is None or inside.returncode != 0:
        R.skip("%s is not a git checkout (or git is missing): nothing is tracked to check" % top)
        return R.finish()
    probs, n = problems_of(top)
    return R.verdict(probs, "none of the %d files git tracks is a generated one" % n)


if __name__ == "__main__":
    sys.exit(main())
