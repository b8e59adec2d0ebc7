# it2n — top-level Makefile. Each directory owns a fragment (*.mk) that adds
# its objects, programs and test targets; this file holds the shared flags.
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

# Fragments append to these.
ALL_TARGETS :=
TEST_TARGETS :=
BENCH_TARGETS :=
FUZZ_TARGETS :=
INSTALL_TARGETS :=

include mk/deps.mk
include firmware_core/core.mk
-include protocol/protocol.mk
include regmap/regmap.mk
include cli/cli.mk
-include daemon/daemon.mk
include tests/tests.mk
-include mk/cross.mk
include mk/lint.mk
include mk/install.mk

.PHONY: all run test bench fuzz cross size install clean deps help

all: $(ALL_TARGETS) ## Build the core, protocol, CLI and daemon

# `make test` runs each TEST_TARGETS entry in turn as its own sub-make
# (builds inside a suite still use -jN) with its output in
# $(BUILD)/logs/SUITE.log, and prints one line per suite: name, ok/FAIL/skip,
# seconds. A failing suite's log is printed in full; V=1 prints every log
# as it runs. It stops at the first failure unless make runs with -k.
# Skips are never "ok": a suite that cannot run prints a line
# "skip suite: REASON" and is listed as skip; a part of a suite that cannot
# run prints "...: skip: REASON" and the suite's line names it. The summary
# counts both, and ends with "suites: N passed, N failed, N skipped".
V ?= 0
test: deps ## Build and run every test, one line per suite (V=1: full output; logs in build/logs/)
	@mkdir -p $(BUILD)/logs; failed=""; t0=$$(date +%s%N); npass=0; nskip=0; nparts=0; \
	keep=$(if $(findstring k,$(firstword -$(MAKEFLAGS))),1,0); \
	for t in $(TEST_TARGETS); do \
	  log=$(BUILD)/logs/$$t.log; s=$$(date +%s%N); \
	  if [ "$(V)" = 1 ]; then \
	    echo "== $$t"; \
	    $(MAKE) --no-print-directory $$t 2>&1 | tee $$log; rc=$${PIPESTATUS[0]}; \
	  else \
	    $(MAKE) --no-print-directory $$t > $$log 2>&1; rc=$$?; \
	  fi; \
	  ds=$$(( ($$(date +%s%N) - s) / 100000000 )); secs=$$((ds / 10)).$$((ds % 10)); \
	  whole=$$(sed -n 's/^skip suite: //p' $$log | head -n 1); \
	  parts=$$(grep -E '^[^ ].*: skip: ' $$log | sed 's/.*: skip: //' | paste -sd ';' -); \
	  if [ $$rc = 0 ] && [ -n "$$whole" ]; then \
	    printf '  %-26s skip %6.1f s  (%s)\n' $$t $$secs "$$whole"; nskip=$$((nskip + 1)); \
	  elif [ $$rc = 0 ]; then \
	    npass=$$((npass + 1)); \
	    if [ -n "$$parts" ]; then \
	      n=$$(grep -cE '^[^ ].*: skip: ' $$log); nparts=$$((nparts + n)); \
	      printf '  %-26s ok   %6.1f s  (%s part(s) skipped: %s)\n' $$t $$secs $$n "$$parts"; \
	    else printf '  %-26s ok   %6.1f s\n' $$t $$secs; fi; \
	  else \
	    [ "$(V)" = 1 ] || { echo "---- $$log"; cat $$log; echo "----"; }; \
	    printf '  %-26s FAIL %6.1f s  (log: %s)\n' $$t $$secs $$log; \
	    failed="$$failed $$t"; [ $$keep = 1 ] || break; \
	  fi; \
	done; \
	secs=$$(( ($$(date +%s%N) - t0) / 1000000000 )); \
	nfail=$$(echo $$failed | wc -w); \
	skips=""; [ $$nskip = 0 ] && [ $$nparts = 0 ] || skips="; $$nskip suite(s) and $$nparts part(s) skipped"; \
	if [ -n "$$failed" ]; then \
	  printf '== FAILED:%s (%.0f s%s) ==\n' "$$failed" $$secs "$$skips"; \
	  printf 'suites: %d passed, %d failed, %d skipped\n' $$npass $$nfail $$nskip; exit 1; \
	fi; \
	printf '== all tests passed (%.0f s%s) ==\n' $$secs "$$skips"; \
	printf 'suites: %d passed, %d failed, %d skipped\n' $$npass $$nfail $$nskip

bench: $(BENCH_TARGETS) ## Run benchmarks (ratios from one run) into bench/*.json, bench/results.json, docs/performance.md
	@$(MAKE) --no-print-directory bench-collect

fuzz: $(FUZZ_TARGETS) ## Run fuzzers for FUZZ_SECONDS each (default 60)

install: $(INSTALL_TARGETS) ## Install programs, units, it2nd.conf, man pages, examples, completions, libit2n.a, headers, it2n.pc (PREFIX, DESTDIR; docs/packaging.md)

clean: ## Remove build output
	rm -rf $(BUILD)

help: ## List targets, then every test suite, benchmark and fuzzer by name
	@grep -hE '^[a-z][a-z_-]*:.*## ' $(MAKEFILE_LIST) | sort -u | \
	  awk -F':.*## ' '{printf "  %-16s %s\n", $$1, $$2}'
	@echo "Test suites (make test runs them in turn; each is also a target):"
	@echo "$(TEST_TARGETS)" | fmt -w 76 | sed 's/^/  /'
	@echo "Benchmarks (make bench runs them all):"
	@echo "$(BENCH_TARGETS)" | fmt -w 76 | sed 's/^/  /'
	@echo "Fuzzers (make fuzz runs them all):"
	@echo "$(FUZZ_TARGETS)" | fmt -w 76 | sed 's/^/  /'
