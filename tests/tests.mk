# Each test area owns a fragment tests/<area>/<area>.mk that appends to
# TEST_TARGETS / BENCH_TARGETS / FUZZ_TARGETS.
-include $(wildcard tests/*/*.mk)

# Suites that measure latency or timing, or whose daemons must not share the
# machine with another suite (tests/run_suites.py runs them alone).
TEST_SOLO += daemon-slowdisk daemon-admit daemon-conn daemon-powercut daemon-diskfull \
             daemon-reload daemon-durability daemon-e2e daemon-sparkplug daemon-fleet \
             daemon-waldamage daemon-metrics proto-daemon proto-e2e fw-e2e fw-reboot fw-survey \
             ctl-test ctl-bspline bench-proto-smoke bench-fc23-smoke soak-smoke cli-test-plot \
             docs-snippets
