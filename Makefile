# it2n — top-level Makefile. Each product directory owns a fragment
# (<dir>/<dir>.mk, core.mk for firmware_core/) with its objects, libraries
# and programs; each test area tests/<area>/<area>.mk its suites
# (tests/tests.mk lists them); mk/ what belongs to no one directory. This
# file holds the shared flags. Every fragment is included with `include`:
# a missing one stops make instead of dropping an area silently.
#   make run   build and start the daemon on its built-in default
#   make test  install missing Debian packages, build, run all tests
.DEFAULT_GOAL := all
SHELL := /bin/bash

PREFIX  ?= /usr/local
DESTDIR ?=
BUILD   ?= build
CC      ?= cc
ifeq ($(CC),cc)
CC := gcc
endif

# The core and protocol: strict C99, warnings are errors.
CORE_WARN := -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion \
             -Wstrict-prototypes -Wmissing-prototypes -Werror
CORE_CFLAGS := -std=c99 -O2 -g $(CORE_WARN) -Ifirmware_core -Iprotocol
# Host programs (CLI, daemon, tests): C11 + POSIX.
HOST_CFLAGS := -std=c11 -D_GNU_SOURCE -O2 -g -Wall -Wextra -Wpedantic -Wshadow -Werror \
               -Ifirmware_core -Iprotocol
# Host builds of the protocol (daemon, CLI, tests, libit2n-dev) keep up to 16
# frames in flight per link (negotiated per peer in HELLO; MCU builds keep
# the default 4). The installed .pc file passes it on (mk/install.mk).
PROTO_HOST_DEFS := -DIT2N_PROTO_WINDOW=16
CORE_CFLAGS += $(PROTO_HOST_DEFS)
HOST_CFLAGS += $(PROTO_HOST_DEFS)
SAN_FLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all
# One version for everything (the file VERSION): it2n, it2nctl and it2nd
# --version (-DIT2N_VERSION), the pkg-config files (mk/install.mk), the
# CMake package (CMakeLists.txt); library.json and debian/changelog repeat
# it, and pkg-version (tests/install/install.mk) checks they all agree.
IT2N_VERSION := $(file <VERSION)
ifeq ($(shell echo '$(IT2N_VERSION)' | grep -xE '[0-9]+\.[0-9]+\.[0-9]+'),)
$(error VERSION: "$(IT2N_VERSION)" is not a version X.Y.Z)
endif
HOST_CFLAGS += -DIT2N_VERSION='"$(IT2N_VERSION)"'

# The user's flags (make CFLAGS=... CPPFLAGS=... LDFLAGS=..., or from the
# environment, as dpkg-buildflags sets them) come after the required ones
# on every host compile and link: they add to -std, the warnings and
# -Werror, they do not replace them. LDFLAGS ride along on compile lines
# too (every host link line carries CORE_CFLAGS or HOST_CFLAGS; gcc ignores
# linker options when it only compiles). Cross and MCU builds take none of
# them. pkg-cflags (tests/install/install.mk) checks every $(CC) line.
USER_FLAGS := $(strip $(CPPFLAGS) $(CFLAGS) $(LDFLAGS))
CORE_CFLAGS += $(USER_FLAGS)
HOST_CFLAGS += $(USER_FLAGS)

# $(call src_list,DIR): the C sources of a library, DIR/sources.txt (one
# file name per line), the one list CMakeLists.txt reads too. Make stops
# when it is not exactly DIR/*.c (a source added but not listed, or gone).
src_list = $(or $(call src_check,$(1),$(addprefix $(1)/,$(file <$(1)/sources.txt))),$(addprefix $(1)/,$(file <$(1)/sources.txt)))
src_check = $(if $(filter-out $(sort $(2)),$(sort $(wildcard $(1)/*.c)))$(filter-out $(sort $(wildcard $(1)/*.c)),$(sort $(2))),$(error $(1)/sources.txt: \
  not listed: $(or $(filter-out $(sort $(2)),$(sort $(wildcard $(1)/*.c))),none); listed but absent: $(or $(filter-out $(sort $(wildcard $(1)/*.c)),$(sort $(2))),none)))

# Fragments append to these.
ALL_TARGETS :=
TEST_TARGETS :=
BENCH_TARGETS :=
FUZZ_TARGETS :=
INSTALL_TARGETS :=

include mk/deps.mk
include firmware_core/core.mk
include protocol/protocol.mk
include regmap/regmap.mk
include cli/cli.mk
include daemon/daemon.mk
include tests/tests.mk
include mk/cross.mk
include mk/lint.mk
include mk/format.mk
include mk/install.mk

.PHONY: all run test bench fuzz cross size install clean deps help

all: $(ALL_TARGETS) ## Build the core, protocol, CLI and daemon

# `make test` runs each TEST_TARGETS entry as its own sub-make with its
# output in $(BUILD)/logs/SUITE.log and prints one line per suite: name,
# ok/FAIL/skip, seconds (tests/run_suites.py). It first builds every suite's
# prerequisites with make -jTEST_JOBS (TEST_BUILD_FIRST in a make of its own
# from the start; the TEST_LIGHT suites start once their part is built),
# then runs up to TEST_JOBS suites at
# once (a suite in TEST_LIGHT, which mostly waits, counts as half); suites in
# TEST_SOLO (timing and latency checks), suites whose recipe runs make and
# suites depending on another suite run alone, with nothing beside them but
# a TEST_BACKGROUND suite at idle priority (tests/tests.mk). A failing
# suite's log is printed in full; V=1 prints every log. It starts no new
# suite after the first failure unless make runs with -k.
# Skips are never "ok": a suite that cannot run prints a line
# "skip suite: REASON" and is listed as skip; a part of a suite that cannot
# run prints "...: skip: REASON" and the suite's line names it. The summary
# counts both, and ends with "suites: N passed, N failed, N skipped".
V ?= 0
TEST_JOBS ?= $(shell nproc 2>/dev/null || echo 1)
test: deps ## Build and run every test, one line per suite (V=1: full output; TEST_JOBS=1: one at a time; logs in build/logs/)
	@/usr/bin/python3 tests/run_suites.py --make "$(MAKE)" --build $(BUILD) --jobs $(TEST_JOBS) \
	  $(if $(findstring k,$(firstword -$(MAKEFLAGS))),--keep) $(if $(filter 1,$(V)),--verbose) \
	  --solo "$(strip $(TEST_SOLO))" --light "$(strip $(TEST_LIGHT))" \
	  --build-first "$(strip $(TEST_BUILD_FIRST))" --background "$(strip $(TEST_BACKGROUND))" \
	  --alone "$(strip $(TEST_SOLO_ALONE))" $(TEST_TARGETS)

# Under `make bench` (and -j), time x86-64 (bench-mcu) only after the other
# benchmarks finish (here, where BENCH_TARGETS holds every *.mk's targets;
# in tests/bench/mcu/mcu.mk it held only the ones included before).
ifneq ($(filter bench,$(MAKECMDGOALS)),)
bench-mcu: | $(filter-out bench-mcu,$(BENCH_TARGETS))
endif

bench: $(BENCH_TARGETS) ## Run benchmarks (time ratios from interleaved rounds, 95 % intervals) into bench/*.json, bench/results.json, docs/performance.md
	@$(MAKE) --no-print-directory bench-collect

fuzz: $(FUZZ_TARGETS) ## Run fuzzers for FUZZ_SECONDS each (default 60)

install: $(INSTALL_TARGETS) ## Install programs, units, it2nd.conf, man pages, examples, completions, libit2n.a, headers, it2n.pc (PREFIX, DESTDIR; docs/packaging.md)

clean: ## Remove build output
	rm -rf $(BUILD)

help: ## List targets, then every test suite, benchmark and fuzzer by name
	@grep -hE '^[a-z][a-z0-9_-]*:.*## ' $(MAKEFILE_LIST) | sort -u | \
	  awk -F':.*## ' '{printf "  %-16s %s\n", $$1, $$2}'
	@echo "Test suites (make test runs them in turn; each is also a target):"
	@echo "$(TEST_TARGETS)" | fmt -w 76 | sed 's/^/  /'
	@echo "Benchmarks (make bench runs them all):"
	@echo "$(BENCH_TARGETS)" | fmt -w 76 | sed 's/^/  /'
	@echo "Fuzzers (make fuzz runs them all):"
	@echo "$(FUZZ_TARGETS)" | fmt -w 76 | sed 's/^/  /'
