# tests/bench/proto/: the serial protocol over a paced, faulty line
# (issue 11). faultrelay paces a pty pair at a baud rate and injects frame
# faults; proto_session runs a host session against a real it2nd.
#   make bench-proto        clean vs 1 % and 10 % faults at 921600 Bd in
#                           interleaved rounds until each ratio's 95 % interval
#                           is within +-5 % (at most 40), durable ingest with
#                           fsync on/off likewise -> bench/proto_loss.json
#   make bench-proto-smoke  (make test) a small session under 10 % faults must
#                           complete with the clean run's results; no time asserted
PB_B := $(BUILD)/bench/proto
PB_RELAY := $(PB_B)/faultrelay
PB_SESSION := $(PB_B)/proto_session

$(PB_RELAY): tests/bench/proto/faultrelay.c
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $< -o $@ -lutil

$(PB_SESSION): tests/bench/proto/proto_session.c examples/instrument/synth.c examples/instrument/synth.h \
               $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -Iexamples/instrument $< examples/instrument/synth.c -o $@ $(PROTO_LIB) $(CORE_LIB)

PB_ENV = BUILD=$(abspath $(BUILD)) IT2ND=$(abspath $(IT2ND)) FAULTRELAY=$(abspath $(PB_RELAY)) \
         PROTO_SESSION=$(abspath $(PB_SESSION))

.PHONY: bench-proto bench-proto-smoke bench-proto-sack
bench-proto: $(PB_RELAY) $(PB_SESSION) $(IT2ND) ## Protocol session under 1 %/10 % line faults, durable ingest (bench/proto_loss.json)
	$(PB_ENV) /usr/bin/python3 tests/bench/proto/bench_proto.py --out bench/proto_loss.json

bench-proto-sack: $(PB_RELAY) $(PB_SESSION) $(IT2ND) ## v1.2 window 16: upload under 10 % faults vs clean, retransmissions under CPU load (bench/proto_sack.json)
	$(PB_ENV) /usr/bin/python3 tests/bench/proto/bench_proto.py --sack --out bench/proto_sack.json

bench-proto-smoke: $(PB_RELAY) $(PB_SESSION) $(IT2ND)
	$(PB_ENV) /usr/bin/python3 tests/bench/proto/bench_proto.py --smoke --out $(BUILD)/bench/proto_loss_smoke.json

BENCH_TARGETS += bench-proto bench-proto-sack
TEST_TARGETS += bench-proto-smoke
