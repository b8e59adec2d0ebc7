# tests/soak/: the it2nd soak (issue 8, "Tests"): 16 Modbus TCP clients
# writing and polling, 3 instrument links, SIGHUP every 2-5 s, kill -9 at
# random moments, failio.so disk faults; checks zero acknowledged operations
# lost (replay into a fresh it2nd, bit-for-bit comparison), zero unexpected
# failures, flat RSS and fd counts. tests/soak/soak.py; docs/daemon.md "Soak".
SOAK_SECONDS ?= 300
SOAK_SMOKE_SECONDS ?= 30
SOAK_DEPS := $(IT2ND) $(SIM_INSTR) $(DT_FAILIO)
SOAK_RUN = /usr/bin/python3 tests/soak/soak.py --it2nd $(IT2ND) --instrument $(SIM_INSTR) --failio $(DT_FAILIO)

.PHONY: soak soak-smoke
soak: $(SOAK_DEPS) ## Soak it2nd for SOAK_SECONDS (default 300): load, SIGHUP, kill -9, disk faults; bench/soak.json
	timeout $$(( $(SOAK_SECONDS) * 2 + 300 )) $(SOAK_RUN) --seconds $(SOAK_SECONDS) --out bench/soak.json

# make test: the same, short (~45 s), figures under build/.
soak-smoke: $(SOAK_DEPS)
	timeout 300 $(SOAK_RUN) --seconds $(SOAK_SMOKE_SECONDS) --out $(BUILD)/soak-smoke.json
TEST_TARGETS += soak-smoke
