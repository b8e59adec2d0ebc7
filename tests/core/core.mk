# tests/core: reference tests of firmware_core against a long-double
# Bernstein-collocation reference (accuracy, validation, operations).
# Each program is built twice: against $(CORE_LIB) and, with $(SAN_FLAGS),
# against $(CORE_SAN_LIB). Targets: core-unit (both), core-unit-plain,
# core-unit-san.
TC_DIR := tests/core
TC_PROGS := test_accuracy test_validation test_operations test_bspline test_eval_exact
TC_COMMON := $(TC_DIR)/ref.c $(TC_DIR)/tc_util.c
TC_HDRS := $(TC_DIR)/ref.h $(TC_DIR)/tc_util.h $(CORE_HDR)
TC_CFLAGS := $(HOST_CFLAGS) -I$(TC_DIR)
TC_LIBS := -lcmocka -lm
TC_BIN := $(TC_PROGS:%=$(BUILD)/tests/core/%)
TC_SAN_BIN := $(TC_PROGS:%=$(BUILD)/tests/core/san/%)

TEST_TARGETS += core-unit

.PHONY: core-unit core-unit-plain core-unit-san

core-unit: core-unit-plain core-unit-san

$(BUILD)/tests/core/%: $(TC_DIR)/%.c $(TC_COMMON) $(TC_HDRS) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(TC_CFLAGS) $< $(TC_COMMON) $(CORE_LIB) $(TC_LIBS) -o $@

$(BUILD)/tests/core/san/%: $(TC_DIR)/%.c $(TC_COMMON) $(TC_HDRS) $(CORE_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(TC_CFLAGS) $(SAN_FLAGS) $< $(TC_COMMON) $(CORE_SAN_LIB) $(TC_LIBS) -o $@

# x86-64 hosts with AVX2 evaluate with it (chosen at run time); the same
# exactness check against a core built without it covers the SSE2 path,
# and the accuracy checks (the summary's bounds and out-of-range flags
# against their own computation) the scalar summary.
TC_EXACT_SSE2 := $(BUILD)/tests/core/test_eval_exact_sse2 $(BUILD)/tests/core/test_accuracy_sse2
$(BUILD)/tests/core/%_sse2: $(TC_DIR)/%.c $(TC_COMMON) $(TC_HDRS) $(CORE_SRC)
	@mkdir -p $(@D)
	$(CC) $(TC_CFLAGS) -DIT2N_NO_AVX2 $< $(TC_COMMON) $(CORE_SRC) $(TC_LIBS) -o $@

# Run every program even when one fails, then fail if any did.
core-unit-plain: $(TC_BIN) $(TC_EXACT_SSE2)
	@rc=0; for t in $(TC_BIN) $(TC_EXACT_SSE2); do echo "== $$t"; $$t || rc=1; done; exit $$rc

core-unit-san: $(TC_SAN_BIN)
	@rc=0; for t in $(TC_SAN_BIN); do echo "== $$t"; \
	  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 $$t || rc=1; \
	done; exit $$rc

# IT2N_CONFIG: the core and a check program built with one config header.
TC_CONFIG_BIN := $(BUILD)/tests/core/test_config
$(TC_CONFIG_BIN): $(TC_DIR)/test_config.c $(TC_DIR)/config/it2n_test_config.h $(CORE_SRC) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) -DIT2N_CONFIG=it2n_test_config.h -I$(TC_DIR)/config \
	  $(TC_DIR)/test_config.c $(CORE_SRC) -o $@

.PHONY: core-config
core-config: $(TC_CONFIG_BIN)
	@$<

TEST_TARGETS += core-config

# The checked-in uniform inverse tables are what their generator prints
# (firmware_core/core.mk: make core-tables).
.PHONY: core-tables-check
core-tables-check:
	@/usr/bin/python3 firmware_core/gen/gen_uniform_inv.py | diff -u firmware_core/it2n_uniform_inv.c - >/dev/null || \
	  { echo "firmware_core/it2n_uniform_inv.c differs from its generator: run 'make core-tables'" >&2; exit 1; }
	@echo "core-tables-check: firmware_core/it2n_uniform_inv.c matches its generator"

TEST_TARGETS += core-tables-check
