# tests/protocol/: the serial protocol (protocol/).
#   proto-unit       unit, golden vector, lossy-channel and fixed-corpus fuzz
#                    runs (cmocka), each built normally and with ASan+UBSan
#   proto-e2e        the example instrument over a lossy pty
#   proto-daemon     protocol v1.1/v1.2 against the real it2nd over a pty
#   proto-inst-size  the instrument API's Cortex-M0+ size in docs/instrument.md
#   proto-fuzz       libFuzzer (make fuzz)
FUZZ_SECONDS ?= 60
PROTO_T := tests/protocol
PROTO_TB := $(BUILD)/tests/protocol
PROTO_TESTS := test_proto test_msg test_link test_inst test_reboot test_vectors lossy fuzz_plain
PROTO_THDR := $(wildcard $(PROTO_T)/*.h)

$(PROTO_TB)/%: $(PROTO_T)/%.c $(PROTO_THDR) $(PROTO_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -I$(PROTO_T) $< -o $@ $(PROTO_LIB) -lcmocka

$(PROTO_TB)/san/%: $(PROTO_T)/%.c $(PROTO_THDR) $(PROTO_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -I$(PROTO_T) $< -o $@ $(PROTO_SAN_LIB) -lcmocka

$(PROTO_TB)/fuzz_plain: $(PROTO_T)/fuzz_proto.c $(PROTO_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -DIT2N_FUZZ_MAIN $< -o $@ $(PROTO_LIB)

$(PROTO_TB)/san/fuzz_plain: $(PROTO_T)/fuzz_proto.c $(PROTO_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -DIT2N_FUZZ_MAIN $< -o $@ $(PROTO_SAN_LIB)

PROTO_TEST_BINS := $(PROTO_TESTS:%=$(PROTO_TB)/%) $(PROTO_TESTS:%=$(PROTO_TB)/san/%)

.PHONY: proto-unit proto-fuzz proto-vectors
TEST_TARGETS += proto-unit

# Unit, golden vector, lossy-channel and fixed-corpus fuzz runs, each built
# normally and with ASan+UBSan.
proto-unit: $(PROTO_TEST_BINS)
	@set -e; for t in $(PROTO_TESTS); do \
	  for b in $(PROTO_TB)/$$t $(PROTO_TB)/san/$$t; do \
	    echo "== $$b"; $$b $(PROTO_T)/corpus protocol/vectors; done; done
	python3 $(PROTO_T)/check_vectors.py protocol/vectors

# Regenerate protocol/vectors/*.hex and protocol/it2n_vectors.inc from the
# message table (only after an intended wire change; review the diff).
proto-vectors: $(PROTO_TB)/gen_vectors ## Regenerate protocol/vectors/ after an intended wire change
	$(PROTO_TB)/gen_vectors protocol/vectors protocol/it2n_vectors.inc $(PROTO_T)/corpus
	python3 $(PROTO_T)/check_vectors.py --update-doc protocol/vectors

# End to end: the example instrument over a lossy pty against a receiver
# built from the link and the core (needs the core library).
PROTO_E2E_DEPS := $(PROTO_T)/test_instrument.c examples/instrument/synth.c \
  examples/instrument/synth.h $(PROTO_THDR)
$(PROTO_TB)/e2e/test_instrument: $(PROTO_E2E_DEPS) $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -I$(PROTO_T) -Iexamples/instrument $(PROTO_T)/test_instrument.c \
	  examples/instrument/synth.c -o $@ $(PROTO_LIB) $(CORE_LIB) -lcmocka

$(PROTO_TB)/e2e/san/test_instrument: $(PROTO_E2E_DEPS) $(PROTO_SAN_LIB) $(CORE_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -I$(PROTO_T) -Iexamples/instrument $(PROTO_T)/test_instrument.c \
	  examples/instrument/synth.c -o $@ $(PROTO_SAN_LIB) $(CORE_SAN_LIB) -lcmocka

.PHONY: proto-e2e
TEST_TARGETS += proto-e2e
proto-e2e: $(PROTO_TB)/e2e/test_instrument $(PROTO_TB)/e2e/san/test_instrument $(BUILD)/host/it2n-instrument
	$(PROTO_TB)/e2e/test_instrument $(BUILD)/host/it2n-instrument
	$(PROTO_TB)/e2e/san/test_instrument $(BUILD)/host/it2n-instrument

# ---- libFuzzer (clang) ----------------------------------------------------
PROTO_FUZZ := $(BUILD)/fuzz/proto_fuzz
FUZZ_TARGETS += proto-fuzz

$(PROTO_FUZZ): $(PROTO_T)/fuzz_proto.c $(PROTO_SRC) $(PROTO_HDR)
	@mkdir -p $(@D)
	clang -std=c11 -g -O1 -fsanitize=fuzzer,address,undefined \
	  -Ifirmware_core -Iprotocol $(PROTO_T)/fuzz_proto.c $(PROTO_SRC) -o $@

proto-fuzz: $(PROTO_FUZZ)
	@mkdir -p $(BUILD)/fuzz/proto_corpus
	$(PROTO_FUZZ) -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 \
	  $(BUILD)/fuzz/proto_corpus $(PROTO_T)/corpus

# ---- against it2nd ----------------------------------------------------------
# Protocol v1.1 against the real daemon over a pty (issue 11): sessions
# that cannot collide, exactly once across kill -9, a lossy line with 0
# host re-requests (tests/protocol/daemon_link.c). Included after
# daemon/daemon.mk (Makefile), so $(IT2ND) is known here.
PROTO_DL := $(BUILD)/tests/protocol/daemon_link
# The worked example of docs/instrument.md, extracted verbatim, compiled
# with the core's warnings (it is firmware code) and run by scenario `doc`.
PROTO_DOC_EX := $(BUILD)/tests/protocol/instrument_example.c
$(PROTO_DOC_EX): docs/instrument.md
	@mkdir -p $(@D)
	awk '/<!-- run: proto-daemon -->/{m=1;next} m && /^```c/{on=1;m=0;next} on && /^```/{on=0} on' $< > $@
	@test -s $@ || { echo "docs/instrument.md: no example block" >&2; exit 1; }
$(BUILD)/tests/protocol/instrument_example.o: $(PROTO_DOC_EX) $(PROTO_HDR)
	$(CC) $(CORE_CFLAGS) -c $< -o $@
$(PROTO_DL): tests/protocol/daemon_link.c examples/instrument/synth.c examples/instrument/synth.h \
  $(BUILD)/tests/protocol/instrument_example.o $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -DDOC_EXAMPLE -Iexamples/instrument tests/protocol/daemon_link.c examples/instrument/synth.c \
	  $(BUILD)/tests/protocol/instrument_example.o -o $@ $(PROTO_LIB) $(CORE_LIB) -lutil

PROTO_DL_ARGS ?= sessions 200 kill 5 lossy 10 reboot 1000 kill12 5 relimit 1 lossy12 10 rebootlossy 100
.PHONY: proto-daemon proto-daemon-long
TEST_TARGETS += proto-daemon
proto-daemon: $(PROTO_DL) $(IT2ND) $(IT2ND_SAN) ## Protocol v1.1/v1.2 against it2nd over a pty (sessions, kill -9, 10% faults, 1000 reboots, spec, doc example)
	timeout 300 $(PROTO_DL) $(IT2ND) $(PROTO_DL_ARGS)
	LINK_EXTRA='peer_timeout_ms = 600' timeout 300 $(PROTO_DL) $(IT2ND) spec 1 doc 2
	LINK_EXTRA='rto_ms = 300' timeout 300 $(PROTO_DL) $(IT2ND) wide 2
	timeout 300 $(PROTO_DL) $(IT2ND_SAN) sessions 20 kill 2 lossy 10 reboot 100
	@# the v1.1 handshake with a fixed session id fails the same test (asserted)
	timeout 60 $(PROTO_DL) $(IT2ND) reboot11 3

proto-daemon-long: $(PROTO_DL) $(IT2ND) ## 1000 back-to-back sessions, 20 kill -9s, 10% and 1% faults, 10000 reboots against it2nd
	timeout 1200 $(PROTO_DL) $(IT2ND) sessions 1000 kill 20 lossy 10 lossy 1 reboot 10000 rebootlossy 1000

# Cortex-M0+ size of the instrument API (the docs/instrument.md example and
# what it links): the figure in docs/instrument.md is checked here; the
# bench rows go to build/ in make test, to bench/ with bench-inst-size.
.PHONY: proto-inst-size bench-inst-size
TEST_TARGETS += proto-inst-size
proto-inst-size: $(PROTO_DOC_EX)
	tests/protocol/inst_size.sh $(PROTO_DOC_EX) $(BUILD)/inst-size --json $(BUILD)/instrument_api.json \
	  --check docs/instrument.md
BENCH_TARGETS += bench-inst-size
bench-inst-size: $(PROTO_DOC_EX) ## Instrument API flash/RAM on Cortex-M0+ (bench/instrument_api.json)
	tests/protocol/inst_size.sh $(PROTO_DOC_EX) $(BUILD)/inst-size --json bench/instrument_api.json
