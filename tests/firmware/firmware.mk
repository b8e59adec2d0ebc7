# tests/firmware/: the instrument firmware of examples/firmware/ on qemu
# mps2-an385 (Cortex-M3), its UART0 on a pty that a real it2nd serves as a
# [link:]; Modbus results must equal the firmware's own evaluations.
#   make fw-image   build the firmware image (ELF + map)
#   make fw-e2e     the end-to-end test, in make test (figures under build/)
#   make bench-firmware  the same, writing the committed bench/firmware.json
FW_B := $(BUILD)/fw-m3
FW_CPU := -mcpu=cortex-m3 -mthumb
FW_SRC := $(wildcard firmware_core/*.c) $(wildcard protocol/*.c) \
          examples/instrument/synth.c examples/instrument/session.c \
          tests/qemu/semihost.c $(wildcard examples/firmware/*.c)
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

.PHONY: fw-image fw-e2e fw-cppcheck
TEST_TARGETS += fw-e2e fw-cppcheck

fw-cppcheck:
	cppcheck --std=c99 $(CPPCHECK_FLAGS) -Iexamples/instrument -Iexamples/firmware -Itests/qemu examples/firmware
fw-image: $(FW_ELF) ## Build only the emulated instrument firmware (build/fw-m3/it2n-firmware.elf)

fw-e2e: $(FW_ELF) $(IT2ND)
	IT2ND=$(IT2ND) FW_ELF=$(FW_ELF) FW_MAP=$(FW_B)/it2n-firmware.map FW_OUT=$(abspath $(BUILD))/firmware.json \
	  tests/firmware/fw_e2e.sh

.PHONY: bench-firmware
bench-firmware: $(FW_ELF) $(IT2ND)
	IT2ND=$(IT2ND) FW_ELF=$(FW_ELF) FW_MAP=$(FW_B)/it2n-firmware.map FW_OUT=$(CURDIR)/bench/firmware.json \
	  tests/firmware/fw_e2e.sh
BENCH_TARGETS += bench-firmware
