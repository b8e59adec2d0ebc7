# tests/fc23/: the FC 23 benchmark (issue 8 item 9). it2nd's full query
# (write q_u, q_w; read the 108 result registers) against a bare libmodbus
# server answering FC 23 of the same sizes, same client load, one run.
# `make bench-fc23` writes bench/fc23.json (ratios at 1, 8, 32 connections,
# targets 1.0, whole 95 % intervals; p99 latency, target at 32); `bench-fc23-smoke` (make test, ~5 s) checks every answer
# under 8 concurrent connections with io = auto and io = epoll, and the
# fallback when a seccomp filter refuses io_uring; never a time.
FC23_B := $(BUILD)/tests/fc23
FC23_LOAD := $(FC23_B)/fc23_load
FC23_BARE := $(FC23_B)/fc23_bare
FC23_NORING := $(FC23_B)/noring

# Clients and a bare server: libmodbus, the core, the CLI's CSV reader for
# the paper data (examples/paper_4x4.csv, what the daemon preloads); no
# daemon header (tests/lint/layers.py).
FC23_CFLAGS := $(HOST_CFLAGS) -Icli/common -Itests/sim $(shell pkg-config --cflags libmodbus 2>/dev/null)
FC23_LIBS := $(shell pkg-config --libs libmodbus 2>/dev/null) -lm -pthread

$(FC23_LOAD): tests/fc23/fc23_load.c tests/sim/simcommon.h $(CLI_CSV_OBJ) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(FC23_CFLAGS) $< $(CLI_CSV_OBJ) -o $@ $(CORE_LIB) $(FC23_LIBS)

$(FC23_BARE): tests/fc23/fc23_bare.c
	@mkdir -p $(@D)
	$(CC) $(FC23_CFLAGS) $< -o $@ $(FC23_LIBS)

# io_uring refused by a seccomp filter: it2nd's io = auto fallback (smoke).
$(FC23_NORING): tests/fc23/noring.c
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $< -o $@

FC23_ARGS = --it2nd $(IT2ND) --bare $(FC23_BARE) --load $(FC23_LOAD)

.PHONY: bench-fc23 bench-fc23-smoke
bench-fc23: $(IT2ND) $(FC23_LOAD) $(FC23_BARE) ## FC 23 query vs bare libmodbus at 1/8/32 connections (bench/fc23.json)
	timeout 600 /usr/bin/python3 tests/fc23/fc23_bench.py $(FC23_ARGS) --out bench/fc23.json

bench-fc23-smoke: $(IT2ND) $(FC23_LOAD) $(FC23_BARE) $(FC23_NORING)
	timeout 120 /usr/bin/python3 tests/fc23/fc23_bench.py $(FC23_ARGS) --noring $(FC23_NORING) --smoke --out $(BUILD)/fc23_smoke.json

# User-space instructions per FC 23 request of each server under callgrind
# (load-independent, unlike the times: for profiling code changes on a
# shared machine; prints, writes no JSON; about 1 minute).
.PHONY: bench-fc23-callgrind
bench-fc23-callgrind: $(IT2ND) $(FC23_LOAD) $(FC23_BARE) ## FC 23 instructions per request, it2nd vs bare libmodbus (callgrind, 1/8/32 connections)
	timeout 600 /usr/bin/python3 tests/fc23/fc23_callgrind.py $(FC23_ARGS)

BENCH_TARGETS += bench-fc23
TEST_TARGETS += bench-fc23-smoke
