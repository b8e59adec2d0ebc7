# tests/sparkplug/: it2nd as a Sparkplug B edge node (issue 16; docs/sparkplug.md)
# against a real mosquitto started on a free loopback port, with a host
# application (paho-mqtt) decoding the payloads independently of the daemon's
# protoc-c code, and pymodbus as the PLC (tests/sparkplug/spb_test.py, ~10 s).
# The ASan+UBSan build runs the births, DDATA, Rebirth and SIGTERM part, and
# the primary host / store-and-forward test with it2nctl spb watch, status
# and eval (spb_sf_test.py, ~10 s).
# make test runs this in three suites: daemon-sparkplug-refusals
# (configuration errors, wrong password, TLS, ACL: spb_test.py --refusals)
# and daemon-sparkplug-sf (spb_sf_test.py) time nothing and share the
# machine (TEST_LIGHT); daemon-sparkplug-node, which times DDATA and Modbus
# answers (the broker stalls), runs alone (TEST_SOLO). `make
# daemon-sparkplug` runs all three.

.PHONY: daemon-sparkplug daemon-sparkplug-node daemon-sparkplug-refusals daemon-sparkplug-sf
TEST_TARGETS += daemon-sparkplug-node daemon-sparkplug-refusals daemon-sparkplug-sf

daemon-sparkplug: daemon-sparkplug-refusals daemon-sparkplug-node daemon-sparkplug-sf ## it2nd as a Sparkplug B edge node against mosquitto (docs/sparkplug.md)

daemon-sparkplug-node: $(IT2ND) $(IT2ND_SAN)
	timeout 120 /usr/bin/python3 tests/sparkplug/spb_test.py --it2nd $(IT2ND) --no-refusals --doc docs/sparkplug.md
	timeout 120 /usr/bin/python3 tests/sparkplug/spb_test.py --it2nd $(IT2ND_SAN) --quick

daemon-sparkplug-refusals: $(IT2ND)
	timeout 120 /usr/bin/python3 tests/sparkplug/spb_test.py --it2nd $(IT2ND) --refusals

daemon-sparkplug-sf: $(IT2ND_SAN) $(CTL_SAN_BIN)
	timeout 60 /usr/bin/python3 tests/sparkplug/spb_sf_test.py --it2nd $(IT2ND_SAN) --it2nctl $(CTL_SAN_BIN)

# A fleet on one broker (issue 16 item 7, docs/fleet.md): 10 it2nd nodes,
# a host application with a persistent session, every birth, a DCMD data
# point per node answered by DDATA (2 rounds), a broker restart (every node
# reborn with a new bdSeq), kill -9 of 3 nodes (an NDEATH with the matching
# bdSeq each) (tests/sparkplug/spb_fleet.py, ~5 s). bench-fleet: 100 nodes,
# 5 rounds, kill -9 of 10, the figures into bench/fleet.json (~20 s).
.PHONY: daemon-fleet bench-fleet
TEST_TARGETS += daemon-fleet
daemon-fleet: $(IT2ND)
	timeout 120 /usr/bin/python3 tests/sparkplug/spb_fleet.py --it2nd $(IT2ND) --nodes 10 --kill 3 --rounds 2

bench-fleet: $(IT2ND) ## 100 it2nd Sparkplug nodes on one mosquitto: births, DDATA p50/p99, rebirth, NDEATH (~20 s)
	timeout 600 /usr/bin/python3 tests/sparkplug/spb_fleet.py --it2nd $(IT2ND) --nodes 100 --kill 10 --rounds 5 \
	  --out bench/fleet.json
BENCH_TARGETS += bench-fleet
