# Each test area owns a fragment tests/<area>/<area>.mk that appends its
# suites to TEST_TARGETS / BENCH_TARGETS / FUZZ_TARGETS. Every area is
# named here: a fragment that is missing or renamed stops make, and one
# that is not listed is refused (no area dropped or added by a wildcard).
# The order is alphabetical (the fragments name each other's files by path).
TEST_AREAS := bench cli cmake_consumer core daemon docs fc23 firmware fuzz_daemon \
              install interop lib protocol qemu regmap soak sparkplug vectors
# it2nctl's suites (tests/cli/ctl.mk) are read with the CLI's.
TEST_MK := $(foreach a,$(TEST_AREAS),tests/$(a)/$(a).mk $(if $(filter cli,$(a)),tests/cli/ctl.mk))
TEST_MK_UNLISTED := $(filter-out $(TEST_MK),$(wildcard tests/*/*.mk))
ifneq ($(TEST_MK_UNLISTED),)
$(error tests/tests.mk: $(TEST_MK_UNLISTED) not in TEST_AREAS: add the area or rename it tests/<area>/<area>.mk)
endif
include $(TEST_MK)

# Suites that measure latency or timing, or whose daemons must not share the
# machine with another suite (tests/run_suites.py runs them alone).
TEST_SOLO += daemon-slowdisk daemon-admit daemon-conn daemon-reload daemon-e2e daemon-sparkplug-node \
             daemon-metrics-latency proto-daemon proto-e2e fw-e2e fw-reboot fw-survey bench-proto-smoke \
             bench-fc23-smoke soak-smoke ctl-e2e daemon-diskfull
# (daemon-diskfull: its "writes refused for 2.5 s while the disk is full"
# phase failed once beside other suites, the refusal window measured 1.08 s,
# and once beside background suites at idle priority (0.06 s): it runs with
# nothing beside it at all, TEST_SOLO_ALONE.)
TEST_SOLO_ALONE += daemon-diskfull
# (ctl-e2e: its plot --follow check expects the generation a push ends on,
# and on a busy machine the follower drew one the push passed through.)
# Not here, so sharing the machine (they time nothing; a slower run is all a
# busy machine does to them): ctl-bspline (answers compared with it2n's,
# bit for bit), docs-snippets.

# Suites that spend their time waiting (daemon starts, fsyncs, timeouts,
# brokers) and time nothing: each counts as half a job, so they run two
# where another suite would run one, beside the other suites.
#   daemon-durability  fault cases: writes for 2.5 s, kill -9, restart, compare
#   daemon-waldamage   damaged WALs: starts refused, kept files compared
#   daemon-fleet       10 nodes on one broker, waits up to 30 s per step
#   daemon-powercut    cuts, restarts and replay-compares (a third of a core)
#   daemon-sparkplug-refusals, daemon-sparkplug-sf  (tests/sparkplug/)
#   daemon-metrics-prom  Prometheus scrapes, waits for values (daemon.mk)
#   ctl-bspline        pushes, reads back and compares bit for bit, kill -9
#                      and restart (times nothing; half its time is waiting
#                      for it2nd and the PLC): it runs beside the build
TEST_LIGHT += daemon-durability daemon-waldamage daemon-fleet daemon-powercut \
              daemon-sparkplug-refusals daemon-sparkplug-sf daemon-metrics-prom ctl-bspline


# Suites that start no daemon, time nothing and wait for nothing but their
# own processes (compilers, cppcheck, lintian, the CLI, unit tests): they
# run beside the solo suites, one at a time at idle priority (SCHED_IDLE,
# idle I/O class: they get a core only when the solo suite leaves it idle,
# which the solo suites, waiting on daemons, links and timers, mostly do).
# What is left of them when the solo suites are done runs as usual. The
# last line's recipes run make, but only make install into a scratch
# directory, make -n, or name make in a message: once everything is built
# they build nothing (after a failed build they run alone).
TEST_BACKGROUND += cmake-consumer cli-plot cli-e2e lint core-unit fuzzd-corpus deb-lintian docs-check \
                   pkg-completion dropin-check cli-docs cross-selftest \
                   pkg-install pkg-cflags deb-smoke deb-contents vectors-current
