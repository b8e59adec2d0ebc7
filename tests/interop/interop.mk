# tests/interop: the Modbus interop traps (word order of 32-bit integers,
# the two views of a query, TCP unit ids 0/255) and the daemon's start-up
# checks, with pymodbus and mbpoll against a real it2nd (interop_test.py).
.PHONY: interop-modbus
interop-modbus: $(BUILD)/host/it2nd $(BUILD)/tests/sim/instrument
	timeout 300 /usr/bin/python3 tests/interop/interop_test.py $(BUILD)/host/it2nd $(BUILD)/tests/sim/instrument

TEST_TARGETS += interop-modbus
