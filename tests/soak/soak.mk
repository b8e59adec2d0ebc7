# tests/soak/: the it2nd soak (issue 8, "Tests"): 16 Modbus TCP clients
# writing and polling, 3 instrument links, SIGHUP every 2-5 s, kill -9 at
# random moments (each a power cut, powercut.so), failio.so disk faults;
# checks zero acknowledged operations
# lost (replay into a fresh it2nd, bit-for-bit comparison), zero unexpected
# failures, flat RSS and fd counts. tests/soak/soak.py; docs/daemon.md "Soak".
SOAK_SECONDS ?= 300
SOAK_SMOKE_SECONDS ?= 30
# (tests/daemon/daemon.mk builds these; named by path, so the order in
# which the fragments are read does not matter)
SOAK_INSTR := $(BUILD)/tests/sim/instrument
SOAK_FAILIO := $(BUILD)/tests/daemon/failio.so
# Every kill -9 of the soak is a power cut (issue 20 item 5): the state
# directory rolled back to what the syncs made durable (powercut.so).
SOAK_POWERCUT := $(BUILD)/tests/daemon/powercut.so
SOAK_DEPS := $(IT2ND) $(SOAK_INSTR) $(SOAK_FAILIO) $(SOAK_POWERCUT)
SOAK_RUN = /usr/bin/python3 tests/soak/soak.py --it2nd $(IT2ND) --instrument $(SOAK_INSTR) --failio $(SOAK_FAILIO) \
  --powercut $(SOAK_POWERCUT)

.PHONY: soak soak-smoke
soak: $(SOAK_DEPS) ## Soak it2nd for SOAK_SECONDS (default 300): load, SIGHUP, kill -9 + power cuts, disk faults; bench/soak.json
	timeout $$(( $(SOAK_SECONDS) * 2 + 300 )) $(SOAK_RUN) --seconds $(SOAK_SECONDS) --out bench/soak.json

# make test: the same, short (~45 s), figures under build/.
soak-smoke: $(SOAK_DEPS)
	timeout 300 $(SOAK_RUN) --seconds $(SOAK_SMOKE_SECONDS) --out $(BUILD)/soak-smoke.json
TEST_TARGETS += soak-smoke

# The soak on the ASan+UBSan build (an error stops the daemon, which fails the
# run; a leak makes the final clean stop's exit status non-zero). Its RSS is
# reported, not checked: the allocator's quarantine grows by design.
SOAK_SAN_SECONDS ?= 120
.PHONY: soak-san
soak-san: $(IT2ND_SAN) $(SOAK_INSTR) $(SOAK_FAILIO) $(SOAK_POWERCUT) ## The soak on the ASan+UBSan build of it2nd (SOAK_SAN_SECONDS, default 120)
	ASAN_OPTIONS=verify_asan_link_order=0 timeout $$(( $(SOAK_SAN_SECONDS) * 2 + 300 )) /usr/bin/python3 \
	  tests/soak/soak.py --it2nd $(IT2ND_SAN) --instrument $(SOAK_INSTR) --failio $(SOAK_FAILIO) --powercut $(SOAK_POWERCUT) \
	  --seconds $(SOAK_SAN_SECONDS) --rss-tol-kib 1048576 --out $(BUILD)/soak-san.json
