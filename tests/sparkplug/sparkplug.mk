# tests/sparkplug/: it2nd as a Sparkplug B edge node (issue 16; docs/sparkplug.md)
# against a real mosquitto started on a free loopback port, with a host
# application (paho-mqtt) decoding the payloads independently of the daemon's
# protoc-c code, and pymodbus as the PLC (tests/sparkplug/spb_test.py, ~10 s).
# The ASan+UBSan build runs the births, DDATA, Rebirth and SIGTERM part.

.PHONY: daemon-sparkplug
TEST_TARGETS += daemon-sparkplug

daemon-sparkplug: $(IT2ND) $(IT2ND_SAN)
	timeout 120 /usr/bin/python3 tests/sparkplug/spb_test.py --it2nd $(IT2ND) --doc docs/sparkplug.md
	timeout 120 /usr/bin/python3 tests/sparkplug/spb_test.py --it2nd $(IT2ND_SAN) --quick
