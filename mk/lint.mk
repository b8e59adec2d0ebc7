# Static analysis: cppcheck must stay clean on every C directory.
CPPCHECK_FLAGS := --enable=warning,portability,performance --error-exitcode=1 -q \
  --inline-suppr --suppress=missingIncludeSystem -Ifirmware_core -Iprotocol

.PHONY: lint
lint:
	cppcheck --std=c99 $(CPPCHECK_FLAGS) -Iregmap firmware_core protocol regmap
	@# Nothing outside the daemon includes daemon/ headers or passes -Idaemon.
	/usr/bin/python3 tests/lint/layers.py --make "$(CLI_BIN) $(CTL_BIN) $(GEN_REGISTERS) $(SIM_PLC) $(SIM_INSTR) $(FC23_LOAD) $(FC23_BARE)"
	cppcheck --std=c11 $(CPPCHECK_FLAGS) -Iregmap -D_GNU_SOURCE $(wildcard cli daemon)

TEST_TARGETS += lint
