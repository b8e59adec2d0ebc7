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
include cli/cli.mk
-include daemon/daemon.mk
include tests/tests.mk
-include mk/cross.mk
include mk/lint.mk
include mk/install.mk

.PHONY: all run test bench fuzz cross size install clean deps help

all: $(ALL_TARGETS) ## Build the core, protocol, CLI and daemon

test: deps ## Build and run every test (unit, reference, sanitizers, emulated Cortex-M3, end-to-end)
	@$(MAKE) --no-print-directory $(TEST_TARGETS)
	@echo "== all tests passed =="

bench: $(BENCH_TARGETS) ## Run benchmarks (ratios from one run) into bench/*.json, bench/results.json, docs/performance.md
	@$(MAKE) --no-print-directory bench-collect

fuzz: $(FUZZ_TARGETS) ## Run fuzzers for FUZZ_SECONDS each (default 60)

install: $(INSTALL_TARGETS) ## Install programs, units, it2nd.conf, man pages, examples, completions, libit2n.a, headers, it2n.pc (PREFIX, DESTDIR; docs/packaging.md)

clean: ## Remove build output
	rm -rf $(BUILD)

help: ## List targets
	@grep -hE '^[a-z][a-z_-]*:.*## ' $(MAKEFILE_LIST) | sort -u | \
	  awk -F':.*## ' '{printf "  %-10s %s\n", $$1, $$2}'
