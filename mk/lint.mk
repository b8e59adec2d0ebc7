# make lint: the static checks, one suite (`lint` in make test).
#   cppcheck over every C directory (product code, the test programs and
#   the example firmware), each set of directories with its C standard,
#   defines and include paths; nothing may be reported
#   tests/cli/fn_length.py: no front-end function over 100 lines
#   tests/lint/layers.py: nothing outside daemon/ includes a daemon/ header
#   or passes -Idaemon (the layers of docs/design.md)
#   tests/lint/names.py: every global symbol of the daemon's, the front
#   ends' and the register map's objects carries its module's prefix, one
#   set of lifecycle verbs (nm; docs/design.md, "Names"); its --selftest
#   first shows it fails on wrong names
#   tests/lint/tracked.py: no generated file (bytecode, logs, build
#   outputs, libFuzzer artefacts) is tracked by git; its --selftest first
#   shows it fails on a scratch repository where one is
#   format-check: the product code laid out as .clang-format says
#   (mk/format.mk; "format-check: skip: ..." without clang-format 14), and
#   tests/lint/format_test.sh, which shows the check fails on mangled code
# (clang-tidy is not used.)
CPPCHECK_FLAGS := --enable=warning,portability,performance --error-exitcode=1 -q \
  --inline-suppr --suppress=missingIncludeSystem -Ifirmware_core -Iprotocol
# Portable C99: the core, the protocol, the register map; the example firmware.
LINT_C99 := cppcheck --std=c99 $(CPPCHECK_FLAGS)
# Host code (C11 + POSIX): the CLI and the daemon, with the version the
# build passes (without it their sources stop with #error).
LINT_C11 := cppcheck --std=c11 $(CPPCHECK_FLAGS) -D_GNU_SOURCE -DIT2N_VERSION='"$(IT2N_VERSION)"'
# The daemon's tests, simulators and fuzz harnesses: warning and portability
# only (their flags before there was one lint target); their include paths
# are the daemon's, so the commands live in the daemon's test areas
# (LINT_DAEMON_TESTS, LINT_FUZZD; tests/lint/layers.py).
LINT_TESTS := cppcheck --std=c11 --enable=warning,portability --error-exitcode=1 -q \
  --suppress=missingIncludeSystem -Ifirmware_core -Iprotocol -Iregmap

# The objects tests/lint/names.py reads (nm), built as the programs are.
LINT_NAMES_OBJ := $(sort $(DAEMON_OBJ) $(CLI_OBJ) $(CTL_SRC:%.c=$(BUILD)/host/%.o) $(REGMAP_OBJ))

.PHONY: lint
lint: $(LINT_NAMES_OBJ) ## Static checks: cppcheck over all C code, layers.py, names.py, tracked.py, format-check
	$(LINT_C99) -Iregmap firmware_core protocol regmap
	$(LINT_C99) -Iexamples/instrument -Iexamples/firmware -Itests/qemu examples/firmware
	$(LINT_C11) -Iregmap -Icli/common -Icli/it2nctl cli daemon
	$(LINT_C11) -Icli/common -Icli/it2nctl tests/cli firmware_core/it2n_text.c
	$(LINT_CLI_FN)
	$(LINT_DAEMON_TESTS)
	$(LINT_FUZZD)
	@# Nothing outside the daemon includes daemon/ headers or passes -Idaemon.
	/usr/bin/python3 tests/lint/layers.py --make "$(CLI_BIN) $(CTL_BIN) $(GEN_REGISTERS) $(SIM_PLC) $(SIM_INSTR) $(FC23_LOAD) $(FC23_BARE)"
	@# One prefix per module, one set of lifecycle verbs.
	/usr/bin/python3 tests/lint/names.py --selftest
	/usr/bin/python3 tests/lint/names.py $(BUILD)/host $(LINT_NAMES_OBJ)
	@# No generated file tracked by git (issue 19: a libFuzzer log was).
	/usr/bin/python3 tests/lint/tracked.py --selftest
	/usr/bin/python3 tests/lint/tracked.py
	@mk/format.sh lint $(FORMAT_FILES)
	@tests/lint/format_test.sh
	@echo "lint: cppcheck clean, layers respected, module prefixes held, no generated file tracked (format-check: above)"

TEST_TARGETS += lint
