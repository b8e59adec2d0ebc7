"""ok / FAIL / skip lines and the exit status, in `make test`'s conventions
(tests/run_suites.py): "NAME: ok: what", "NAME: FAIL: what" (on stderr),
"NAME: skip: reason" for a part that could not run, "skip suite: reason" when
nothing could run. A skip is never printed as ok.

    R = report.Report("reload")
    R.check(cond, "what was asserted", detail)
    ...
    sys.exit(R.finish())
"""
import shutil
import sys


class Report:
    def __init__(self, name, quiet_ok=False):
        """name prefixes every line; quiet_ok: print only failures and skips
        (scripts with thousands of checks)."""
        self.name = name
        self.quiet_ok = quiet_ok
        self.checks = 0
        self.fails = []
        self.skips = []

    def ok(self, what):
        self.checks += 1
        if not self.quiet_ok:
            print("%s: ok: %s" % (self.name, what), flush=True)

    def fail(self, what):
        self.checks += 1
        self.fails.append(what)
        sys.stdout.flush()
        print("%s: FAIL: %s" % (self.name, what), file=sys.stderr, flush=True)

    def check(self, cond, what, detail=""):
        """ok when cond is true, FAIL (with detail) when not; returns cond."""
        if cond:
            self.ok(what)
        else:
            d = "" if detail is None or detail == "" else ": " + str(detail)
            self.fail(what + d)
        return cond

    def skip(self, reason):
        """A part that cannot run here: said, counted, never ok."""
        self.skips.append(reason)
        print("%s: skip: %s" % (self.name, reason), flush=True)

    def skip_suite(self, reason):
        """Nothing of the suite can run here: say so and exit 0."""
        print("skip suite: %s" % reason, flush=True)
        sys.exit(0)

    def verdict(self, problems, summary):
        """For a checker that collects problems (lint, docs, packaging):
        each one a FAIL, or, when there are none, summary as the one ok.
        The exit status (finish without its summary line)."""
        for p in problems:
            self.fail(p)
        if not problems:
            self.ok(summary)
        return self.finish(summary=False)

    def tidy(self, tmp, log=None, tail=3000):
        """After a run: on a failure, the last tail characters of log (a
        path) on stderr and tmp kept (said); otherwise tmp removed."""
        if not self.fails:
            shutil.rmtree(tmp, ignore_errors=True)
            return
        if log:
            try:
                with open(log, errors="replace") as f:
                    sys.stderr.write(f.read()[-tail:])
            except OSError:
                pass
        print("%s: logs kept in %s" % (self.name, tmp), file=sys.stderr, flush=True)

    def finish(self, summary=True):
        """Exit status for sys.exit(): 1 when a check failed, or when no check
        ran and nothing was skipped (a script that asserted nothing has not
        passed); 0 otherwise."""
        if not self.checks and not self.skips:
            self.fail("no check ran")
        if summary:
            if self.fails:
                print("%s: %d of %d check(s) FAILED" % (self.name, len(self.fails), self.checks),
                      file=sys.stderr, flush=True)
            else:
                print("%s: all %d check(s) passed%s" % (
                    self.name, self.checks, "; %d part(s) skipped" % len(self.skips) if self.skips else ""),
                    flush=True)
        return 1 if self.fails else 0
