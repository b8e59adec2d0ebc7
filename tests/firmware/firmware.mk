# tests/firmware/: the instrument firmware of examples/firmware/ on qemu
# mps2-an385 (Cortex-M3), its UART0 on a pty that a real it2nd serves as a
# [link:]; Modbus results must equal the firmware's own evaluations.
#   make fw-image   build the firmware image (ELF + map)
#   make fw-e2e     the end-to-end test, in make test (figures under build/)
#   make bench-firmware  the same in rounds (FW_ROUNDS), writing the committed
#                        bench/firmware.json
FW_B := $(BUILD)/fw-m3
FW_CPU := -mcpu=cortex-m3 -mthumb
FW_SRC := $(CORE_SRC) $(PROTO_SRC) \
          examples/instrument/synth.c examples/instrument/session.c \
          tests/qemu/semihost.c $(filter-out examples/firmware/survey.c,$(wildcard examples/firmware/*.c))
FW_HDR := $(wildcard firmware_core/*.h protocol/*.h protocol/*.inc examples/firmware/*.h) \
          examples/instrument/synth.h examples/instrument/session.h tests/qemu/semihost.h
FW_CFLAGS := -ffreestanding -std=c99 -Os -g $(CORE_WARN) -ffunction-sections -fdata-sections \
             -fstack-usage -fcallgraph-info=su \
             -Ifirmware_core -Iprotocol -Iexamples/instrument -Iexamples/firmware -Itests/qemu
FW_OBJ := $(FW_SRC:%.c=$(FW_B)/%.o)
FW_ELF := $(FW_B)/it2n-firmware.elf

$(FW_B)/%.o: %.c $(FW_HDR) tests/firmware/firmware.mk
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(FW_CPU) $(FW_CFLAGS) -c $< -o $@

$(FW_ELF): $(FW_OBJ) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(FW_CPU) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-e,fw_reset_handler -Wl,-Map=$(FW_B)/it2n-firmware.map -o $@ $(FW_OBJ) -lc -lgcc

.PHONY: fw-image fw-e2e
TEST_TARGETS += fw-e2e

fw-image: $(FW_ELF) ## Build only the emulated instrument firmware (build/fw-m3/it2n-firmware.elf)

fw-e2e: $(FW_ELF) $(IT2ND)
	IT2ND=$(IT2ND) FW_ELF=$(FW_ELF) FW_MAP=$(FW_B)/it2n-firmware.map FW_OUT=$(abspath $(BUILD))/firmware.json \
	  tests/firmware/fw_e2e.sh

# The reboot test's image: the same firmware, its measurement chosen per
# boot by the host (FW_REBOOT_TEST, see examples/firmware/firmware.c).
FWR_B := $(BUILD)/fw-m3-reboot
FWR_OBJ := $(FW_SRC:%.c=$(FWR_B)/%.o)
FWR_ELF := $(FWR_B)/it2n-firmware-reboot.elf
$(FWR_B)/%.o: %.c $(FW_HDR) tests/firmware/firmware.mk
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(FW_CPU) $(FW_CFLAGS) -DFW_REBOOT_TEST -c $< -o $@
$(FWR_ELF): $(FWR_OBJ) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(FW_CPU) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-e,fw_reset_handler -o $@ $(FWR_OBJ) -lc -lgcc

# ... and with the v1.1 handshake of the example before 1.2 (FW_V11_HANDSHAKE)
FWR11_B := $(BUILD)/fw-m3-reboot11
FWR11_OBJ := $(FW_SRC:%.c=$(FWR11_B)/%.o)
FWR11_ELF := $(FWR11_B)/it2n-firmware-reboot11.elf
$(FWR11_B)/%.o: %.c $(FW_HDR) tests/firmware/firmware.mk
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(FW_CPU) $(FW_CFLAGS) -DFW_REBOOT_TEST -DFW_V11_HANDSHAKE -c $< -o $@
$(FWR11_ELF): $(FWR11_OBJ) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(FW_CPU) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-e,fw_reset_handler -o $@ $(FWR11_OBJ) -lc -lgcc

# Exactly once across reboots on qemu (docs/protocol.md 4.1): the firmware
# reset at random points (monitor system_reset, deterministic -icount
# timing: every boot alike), alternating two measurements, one daemon and
# one open line throughout; the last boot's results must be bit-identical
# over the link and Modbus. FW_REBOOTS boots before it.
.PHONY: fw-reboot fw-reboot-long
TEST_TARGETS += fw-reboot
fw-reboot: $(FWR_ELF) $(IT2ND) ## Firmware on qemu reset at 30 random points, exactly once across reboots
	IT2ND=$(IT2ND) FW_ELF=$(FWR_ELF) FW_REBOOTS=$${FW_REBOOTS:-30} tests/firmware/fw_reboot.sh
fw-reboot-long: $(FWR_ELF) $(IT2ND) ## The same with 300 resets
	IT2ND=$(IT2ND) FW_ELF=$(FWR_ELF) FW_REBOOTS=300 tests/firmware/fw_reboot.sh
# The old handshake fails it (asserted: the script must report a failure).
.PHONY: fw-reboot-legacy
fw-reboot-legacy: $(FWR11_ELF) $(IT2ND) ## fw-reboot with the v1.1 handshake (clock-derived id): must fail
	IT2ND=$(IT2ND) FW_ELF=$(FWR11_ELF) FW_REBOOTS=$${FW_REBOOTS:-10} FW_EXPECT_FAIL=1 tests/firmware/fw_reboot.sh

.PHONY: bench-firmware
# at most this many rounds of a direct and a lossy upload (fw_e2e.sh)
FW_ROUNDS ?= 10
bench-firmware: $(FW_ELF) $(IT2ND)
	IT2ND=$(IT2ND) FW_ELF=$(FW_ELF) FW_MAP=$(FW_B)/it2n-firmware.map FW_OUT=$(CURDIR)/bench/firmware.json \
	  FW_ROUNDS=$(FW_ROUNDS) tests/firmware/fw_e2e.sh
BENCH_TARGETS += bench-firmware

# ---- the survey image: issue 21's Done-when leg --------------------------
# examples/firmware/survey.c: the survey CSV compiled into flash, parsed and
# solved by the core on the device (static storage for FW_BSPLINE_MAX_N x
# FW_BSPLINE_MAX_M intervals, IT2N_BSPLINE_MAX_N set to match: an MCU build
# bounds the solve stack by its largest grid). fw-survey: the same file goes
# through `it2nctl push --kind bspline --link` (protocol v1.3) into it2nd, a
# PLC reads the daemon's answers over Modbus TCP and they must be bit for bit
# the firmware's own evaluations at 320 points; then it2nctl plots it.
FWS_B := $(BUILD)/fw-m3-survey
FW_SURVEY_CSV ?= examples/survey_64x64.csv
FWS_MAX ?= 63
FWS_SRC := $(CORE_SRC) tests/qemu/semihost.c examples/firmware/startup.c \
           examples/firmware/board.c examples/firmware/fw_print.c examples/firmware/survey.c
FWS_CFLAGS := $(FW_CFLAGS) -DFW_PRINT_LINE=2048u -DIT2N_BSPLINE_MAX_N=$(FWS_MAX) -DFW_BSPLINE_MAX_N=$(FWS_MAX) -DFW_BSPLINE_MAX_M=$(FWS_MAX)
FWS_OBJ := $(FWS_SRC:%.c=$(FWS_B)/%.o) $(FWS_B)/survey_csv.o
FWS_ELF := $(FWS_B)/it2n-survey.elf

$(FWS_B)/%.o: %.c $(FW_HDR) tests/firmware/firmware.mk
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(FW_CPU) $(FWS_CFLAGS) -c $< -o $@

# The survey in flash: its bytes (fw_survey_csv) and their count (fw_survey_csv_len).
$(FWS_B)/survey_csv.o: $(FW_SURVEY_CSV) tests/firmware/firmware.mk
	@mkdir -p $(@D)
	printf '.section .rodata.survey_csv,"a"\n.global fw_survey_csv\n.global fw_survey_csv_len\nfw_survey_csv:\n.incbin "%s"\n1:\n.balign 4\nfw_survey_csv_len:\n.word 1b - fw_survey_csv\n' \
	  "$(abspath $(FW_SURVEY_CSV))" > $(FWS_B)/survey_csv.S
	arm-none-eabi-gcc $(FW_CPU) -c $(FWS_B)/survey_csv.S -o $@

$(FWS_ELF): $(FWS_OBJ) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(FW_CPU) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-e,fw_reset_handler -Wl,-Map=$(FWS_B)/it2n-survey.map -o $@ $(FWS_OBJ) -lc -lgcc

.PHONY: fw-survey
TEST_TARGETS += fw-survey
fw-survey: $(FWS_ELF) $(IT2ND) $(CTL_BIN) $(BUILD)/tests/sim/ptybridge ## 64x64 survey: CSV -> it2nctl push --link -> it2nd -> PLC, bit for bit with the core on emulated Cortex-M3; plotted
	IT2ND=$(IT2ND) CTL=$(CTL_BIN) PTY=$(BUILD)/tests/sim/ptybridge FW_ELF=$(FWS_ELF) SURVEY=$(FW_SURVEY_CSV) \
	  FW_OUT=$(abspath $(BUILD))/fw-survey timeout 300 /usr/bin/python3 tests/firmware/fw_survey.py
