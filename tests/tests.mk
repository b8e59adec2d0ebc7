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
TEST_SOLO += daemon-slowdisk daemon-admit daemon-conn daemon-powercut daemon-diskfull \
             daemon-reload daemon-durability daemon-e2e daemon-sparkplug daemon-fleet \
             daemon-waldamage daemon-metrics proto-daemon proto-e2e fw-e2e fw-reboot fw-survey \
             ctl-e2e ctl-bspline bench-proto-smoke bench-fc23-smoke soak-smoke \
             docs-snippets
