# Each test area owns a fragment tests/<area>/<area>.mk that appends to
# TEST_TARGETS / BENCH_TARGETS / FUZZ_TARGETS.
-include $(wildcard tests/*/*.mk)
