#!/usr/bin/python3
"""run_suites.py -- `make test`'s runner: every TEST_TARGETS suite as its own
sub-make, one line per suite (name, ok/FAIL/skip, seconds), logs in
BUILD/logs/SUITE.log.

  run_suites.py --make MAKE --build BUILD [--jobs N] [--keep] [--verbose]
                [--solo "SUITE ..."] [--light "SUITE ..."] [--build-first "TARGET ..."]
                [--background "SUITE ..."] [--alone "SUITE ..."] SUITE ...

Why a runner and not a shell loop: CI machines have 2 cores and most suites
spend their time waiting on daemons, links and brokers, so running them one
after another left a core idle for most of `make test`. The runner

  1. builds every prerequisite of every suite first, with -jN -k (so two
     suites never build the same file at once; a prerequisite that does not
     build is reported by the suite that needs it, whose own sub-make
     retries it and logs the error), in up to three makes, each target in
     one of them only: the BUILD_FIRST targets (TEST_BUILD_FIRST: long
     chains of steps that make cannot spread over the cores, such as the
     Debian packages, built in their own directory) in their own make,
     started at once (named first in one make they still waited for a free
     job slot, and started late); beside it the prerequisites of the light
     suites, then the rest. The light suites start as soon as their part is
     built and wait beside the compilers (after a failed build, every suite
     waits for every build);
  2. then runs the suites that may share the machine, up to N at once, and
     after them the solo ones, one at a time. A suite runs alone ("solo")
     when it measures latency or timing (the SOLO list, TEST_SOLO in the
     makefiles), when its recipe runs make itself, or when it depends on
     another suite (that one finishes first). A "light" suite (the LIGHT
     list, TEST_LIGHT) spends its time waiting (daemons, timeouts, links)
     and asserts no latency: it counts as half a job, so two of them run
     where one other suite would. Light suites start first (they are the
     long ones), at most N at once, the others fill the rest, so the shared
     part ends with short suites rather than with one long wait holding the
     solo ones back. A "background" suite (the BACKGROUND list,
     TEST_BACKGROUND: no daemon, no timing, only its own processes) waits
     for the solo part and runs beside the solo suites, up to N-1 at once,
     at idle priority (SCHED_IDLE and the idle I/O class: a core only when
     the solo suite leaves it idle, which waiting on daemons, links and
     timers it mostly does); those left when no solo suite is left run as
     the shared ones do (an ALONE suite, TEST_SOLO_ALONE, has no
     background suite beside it either). A background suite whose recipe runs make (make
     install into a scratch directory, make -n) is one too, since
     everything is built by then; after a failed build it runs alone.

Lines are printed as suites finish. Skips are never "ok": a suite that
cannot run prints "skip suite: REASON" and is listed as skip; a part that
cannot run prints "...: skip: REASON" and the suite's line names it. The
summary counts both and ends with "suites: N passed, N failed, N skipped".
Without --keep the runner starts no new suite after the first failure.
"""
import argparse
import os
import re
import subprocess
import sys
import time


def database(make):
    """Rules of the makefile database: target -> (prerequisites, recipe)."""
    env = dict(os.environ)
    env.pop("MAKEFLAGS", None)
    env.pop("MFLAGS", None)
    out = subprocess.run([make, "-pq", "--no-print-directory"], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True, errors="replace").stdout
    rules, files, target = {}, False, None
    for line in out.splitlines():
        if line.startswith("# Files"):
            files = True
            continue
        if not files:
            continue
        if line.startswith("\t") and target is not None:
            rules[target][1].append(line[1:])
            continue
        if not line or line.startswith("#"):
            target = None if not line else target
            continue
        m = re.match(r"^([^\s:=#][^:=]*?):(?!=)\s*(.*)$", line)
        if m and " " not in m.group(1):
            target = m.group(1)
            prereqs = m.group(2).split("|")[0].split()
            if target not in rules:
                rules[target] = (prereqs, [])
        else:
            target = None
    return rules


LIGHT_WEIGHT = 0.5  # of a job: a suite that mostly waits


def classify(suites, solo, rules, light=()):
    """Each suite's build prerequisites, the suites it waits for, whether
    it runs alone and its share of a job when it does not."""
    info = {}
    names = set(suites)
    phony = set(rules.get(".PHONY", ([], []))[0])

    def files(p, seen):
        # A phony prerequisite with a recipe (core-unit-plain: it runs the
        # tests) would run in the first step and again in the suite: the
        # first step builds what it needs instead.
        if p not in phony or not rules.get(p, ([], []))[1]:
            return [p]
        out = []
        for q in rules[p][0]:
            if q not in seen:
                seen.add(q)
                out += files(q, seen)
        return out
    for s in suites:
        prereqs, recipe = rules.get(s, ([], []))
        after = [p for p in prereqs if p in names]
        build, seen = [], set()
        for p in prereqs:
            if p not in names and p != "deps":
                build += [q for q in files(p, seen) if q not in build and q not in names and q != "deps"]
        makes = any(re.search(r"\$\(MAKE\)|\$\{MAKE\}|(^|[\s;&|(])make\s", r) for r in recipe)
        alone = s in solo or makes or bool(after)
        info[s] = {"build": build, "after": after, "solo": alone, "makes": makes and s not in solo and not after,
                   "weight": LIGHT_WEIGHT if s in light and not alone else 1.0}
    return info


def summary_line(name, rc, secs, log):
    text = open(log, encoding="utf-8", errors="replace").read() if os.path.exists(log) else ""
    whole = re.search(r"^skip suite: (.*)$", text, re.M)
    parts = re.findall(r"^[^ \n].*?: skip: (.*)$", text, re.M)
    if rc == 0 and whole:
        return "skip", "  %-26s skip %6.1f s  (%s)" % (name, secs, whole.group(1)), 0
    if rc == 0:
        if parts:
            return "ok", "  %-26s ok   %6.1f s  (%d part(s) skipped: %s)" % (
                name, secs, len(parts), ";".join(parts)), len(parts)
        return "ok", "  %-26s ok   %6.1f s" % (name, secs), 0
    return "FAIL", "  %-26s FAIL %6.1f s  (log: %s)" % (name, secs, log), 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--make", default="make")
    ap.add_argument("--build", default="build")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("--verbose", action="store_true")
    ap.add_argument("--solo", default="")
    ap.add_argument("--light", default="")
    ap.add_argument("--build-first", default="")
    ap.add_argument("--background", default="")
    ap.add_argument("--alone", default="")
    ap.add_argument("suites", nargs="+")
    a = ap.parse_args()
    logs = os.path.join(a.build, "logs")
    os.makedirs(logs, exist_ok=True)
    env = dict(os.environ)
    for k in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL"):
        env.pop(k, None)
    t0 = time.monotonic()

    info = classify(a.suites, set(a.solo.split()), database(a.make), set(a.light.split()))
    build = []
    for s in a.suites:
        build += [p for p in info[s]["build"] if p not in build]
    first = [p for p in a.build_first.split() if p in build]
    build = first + [p for p in build if p not in first]
    jobs = max(1, a.jobs)
    if jobs == 1:   # TEST_JOBS=1: one suite at a time, light or not
        for i in info.values():
            i["weight"] = 1.0
    # Background suites: not solo, and never beside a solo one but at idle
    # priority (TEST_JOBS=1: none).
    # A background suite whose recipe runs make (make install into a scratch
    # directory, make -n) runs beside a solo one too: every prerequisite is
    # built by then, its make only reads the build. After a failed build it
    # is solo again (its make would retry what failed).
    bg_names = set(a.background.split()) if jobs > 1 else set()
    alone = set(a.alone.split())   # solo ones with no background suite beside them either
    for n, i in info.items():
        i["bg"] = n in bg_names and (not i["solo"] or i["makes"])
        if i["bg"]:
            i["solo"] = False
    # The first step, in up to three makes: the BUILD_FIRST targets (their
    # own make, started at once: a long chain such as the Debian packages,
    # built in its own directory, must not wait for a free job slot behind
    # the others), the prerequisites of the light suites (stage 1), then the
    # rest (stage 2). The light suites start as soon as stage 1 is built
    # and wait through stage 2 beside the compilers; the other suites wait
    # for every build. Each target is built by one make only.
    light_build = []
    for s_ in a.suites:
        if info[s_]["weight"] < 1:
            light_build += [p for p in info[s_]["build"] if p not in first and p not in light_build]
    rest = [p for p in build if p not in first and p not in light_build]
    stages = [("first", first), ("stage1", light_build), ("stage2", rest)]
    owner = {}
    for sname, targets in stages:
        for p in targets:
            owner[p] = sname
    builds = {}    # stage -> [Popen or None, start, rc, log, logfile]
    bstart = time.monotonic()

    def start_build(sname):
        targets = dict(stages)[sname]
        if not targets:
            builds[sname] = [None, time.monotonic(), 0, None, None]
            return
        log = os.path.join(logs, "_prerequisites.log" if sname != "first" else "_prerequisites-first.log")
        lf = open(log, "a" if sname == "stage2" else "w")
        p = subprocess.Popen([a.make, "--no-print-directory", "-k", "-j%d" % jobs] + targets,
                             stdout=lf, stderr=subprocess.STDOUT, env=env)
        builds[sname] = [p, time.monotonic(), None, log, lf]

    def poll_builds():
        """Reap finished builds, start stage 2 after stage 1; True while
        any build runs."""
        for sname in ("first", "stage1", "stage2"):
            b = builds.get(sname)
            if b is None or b[2] is not None:
                continue
            rc = b[0].poll()
            if rc is None:
                continue
            b[2] = rc
            b[4].close()
        if "stage2" not in builds and builds["stage1"][2] is not None:
            start_build("stage2")
        running_b = any(b[2] is None for b in builds.values()) or "stage2" not in builds
        if not running_b and not reported[0]:
            reported[0] = True
            failed_b = [n for n, b in builds.items() if b[2] != 0]
            for i in info.values():
                if failed_b and i["bg"] and i["makes"]:
                    i["bg"], i["solo"] = False, True
            print("  %-26s %-4s %6.1f s  (%d targets, -j%d; light suites from %.0f s%s)" % (
                "(prerequisites)", "ok" if not failed_b else "part", time.monotonic() - bstart, len(build), jobs,
                builds["stage2"][1] - bstart,
                "" if not failed_b else "; what failed is reported by its suites, log: " + " ".join(
                    sorted(set(builds[n][3] for n in failed_b)))), flush=True)
        return running_b

    def built(name):
        """May suite `name` start as far as the first step goes: every make
        building one of its prerequisites finished, with no failure in any
        build (after a failure, suites wait for all builds, so that a suite's
        own make retrying a target never runs beside a make building it)."""
        if any(b[2] is not None and b[2] != 0 for b in builds.values()) or "stage2" not in builds:
            return not any(b[2] is None for b in builds.values()) and "stage2" in builds
        return all(builds[owner[p]][2] is not None for p in info[name]["build"] if p in owner)

    reported = [False]
    start_build("first")
    start_build("stage1")
    pending = list(a.suites)
    running = {}   # name -> (Popen, start, log, logfile)
    done = {}      # name -> status
    failed, npass, nskip, nparts = [], 0, 0, 0
    stop = False

    idle = set()   # the suites started at idle priority (beside a solo one)

    def idle_priority():
        # in the child, before exec: SCHED_IDLE (a core only when no other
        # process wants it; its children inherit it)
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))

    def start(name, solo, background=False):
        log = os.path.join(logs, name + ".log")
        lf = open(log, "w")
        cmd = [a.make, "--no-print-directory"] + (["-j%d" % jobs] if solo else []) + [name]
        if a.verbose:
            print("== " + name, flush=True)
        if background:
            # and the idle I/O class: its disk I/O waits for the solo one's
            if os.path.exists("/usr/bin/ionice"):
                cmd = ["/usr/bin/ionice", "-c3"] + cmd
            idle.add(name)
        p = subprocess.Popen(cmd, stdout=lf, stderr=subprocess.STDOUT, env=env,
                             preexec_fn=idle_priority if background else None)
        running[name] = (p, time.monotonic(), log, lf)

    while True:
        building = poll_builds()
        if not running and (stop or not pending):
            break
        # start what can start: the suites that may share the machine
        # first, as many as fit in `jobs` (a light suite counts as half a
        # job; light ones first, but no more than `jobs` of them, so the
        # waiting ones never hold every core back from the others; then in
        # TEST_TARGETS order); the solo ones after them, one at a time with
        # nothing else running but background suites: each solo suite has
        # up to jobs-1 of them beside it at idle priority (they take what
        # the solo suite leaves of the cores); the background suites left
        # when no solo suite is left run as the shared ones do. While the
        # first step still builds, only light suites whose prerequisites
        # are built start (the build has the cores; they wait beside it).
        while pending and not stop:
            ready = [n for n in pending if all(d in done for d in info[n]["after"]) and built(n)]
            solo_running = any(info[n]["solo"] for n in running)
            others_left = any(not info[n]["solo"] and not info[n]["bg"] for n in pending)
            if solo_running:
                bgs = [n for n in ready if info[n]["bg"]]
                if bgs and not building and sum(1 for n in running if n in idle) < jobs - 1 and \
                        not any(n in alone for n in running):
                    nxt = bgs[0]
                    pending.remove(nxt)
                    start(nxt, False, background=True)
                    continue
                break
            free = jobs - sum(info[n]["weight"] for n in running)
            lights = sum(1 for n in running if info[n]["weight"] < 1)
            shared = [n for n in ready if not info[n]["solo"] and info[n]["weight"] <= free and
                      (not info[n]["bg"] or not (others_left or any(info[m]["solo"] for m in ready))) and
                      (info[n]["weight"] == 1 or lights < jobs) and (not building or info[n]["weight"] < 1)]
            shared.sort(key=lambda n: info[n]["weight"])
            if shared:
                nxt = shared[0]
            elif (ready and not building and not others_left and all(n in idle for n in running)
                  and any(info[n]["solo"] and (n not in alone or not running) for n in ready)):
                nxt = [n for n in ready if info[n]["solo"] and (n not in alone or not running)][0]
            else:
                break
            pending.remove(nxt)
            start(nxt, info[nxt]["solo"] or jobs == 1)
        time.sleep(0.1)
        for name in list(running):
            p, st, log, lf = running[name]
            rc = p.poll()
            if rc is None:
                continue
            lf.close()
            del running[name]
            status, line, parts = summary_line(name, rc, time.monotonic() - st, log)
            done[name] = status
            if status == "FAIL":
                if not a.verbose:
                    print("---- " + log)
                    sys.stdout.write(open(log, encoding="utf-8", errors="replace").read())
                    print("----")
                failed.append(name)
                stop = stop or not a.keep
            elif status == "skip":
                nskip += 1
            else:
                npass += 1
                nparts += parts
            if a.verbose:
                sys.stdout.write(open(log, encoding="utf-8", errors="replace").read())
            print(line, flush=True)

    for b in builds.values():   # stopped after a failure: no make left behind
        if b[2] is None:
            b[0].terminate()
            b[0].wait()
            b[4].close()
    secs = time.monotonic() - t0
    skips = "" if nskip == 0 and nparts == 0 else "; %d suite(s) and %d part(s) skipped" % (nskip, nparts)
    if failed or pending:
        print("== FAILED: %s (%.0f s%s) ==" % (" ".join(failed), secs, skips))
        if pending:
            print("not run after the failure: " + " ".join(pending))
        print("suites: %d passed, %d failed, %d skipped" % (npass, len(failed), nskip))
        return 1
    print("== all tests passed (%.0f s%s) ==" % (secs, skips))
    print("suites: %d passed, %d failed, %d skipped" % (npass, len(failed), nskip))
    return 0


if __name__ == "__main__":
    sys.exit(main())
