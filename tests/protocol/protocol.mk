# Protocol v1.1 against the real daemon over a pty (issue 11): sessions
# that cannot collide, exactly once across kill -9, a lossy line with 0
# host re-requests (tests/protocol/daemon_link.c). Included after
# daemon/daemon.mk (tests/tests.mk), so $(IT2ND) is known here.
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
