# tests/qemu/: the core test vectors (and the protocol self-test, once
# protocol/it2n_selftest.c exists) on an emulated Cortex-M3:
#   qemu-system-arm -M mps2-an385 -semihosting-config enable=on,target=native
# Freestanding image: startup.c (vectors, reset), mps2_an385.ld, semihost.c.
# The model structs live in .bss (4 MB SSRAM), the 64 KB stack below them.
QEMU_DIR := tests/qemu
QEMU_B   := $(BUILD)/qemu-m3
QEMU_ELF := $(QEMU_B)/it2n-m3.elf
QEMU_TIMEOUT ?= 120
QEMU_CPU := -mcpu=cortex-m3 -mthumb
QEMU_HAVE_SELFTEST := $(wildcard protocol/it2n_selftest.c)
QEMU_SRC := $(wildcard firmware_core/*.c) \
            tests/vectors/core_vectors.c tests/vectors/vec_scenarios.c tests/vectors/vec_paper.c \
            $(QEMU_DIR)/main.c $(QEMU_DIR)/startup.c $(QEMU_DIR)/semihost.c \
            $(if $(QEMU_HAVE_SELFTEST),$(wildcard protocol/*.c))
QEMU_HDR := $(wildcard firmware_core/*.h protocol/*.h protocol/*.inc tests/vectors/*.h $(QEMU_DIR)/*.h)
QEMU_CFLAGS := $(QEMU_CPU) -ffreestanding -std=c99 -Os -g $(CORE_WARN) \
               -ffunction-sections -fdata-sections \
               -Ifirmware_core -Iprotocol -Itests/vectors -I$(QEMU_DIR) \
               $(if $(QEMU_HAVE_SELFTEST),-DIT2N_HAVE_PROTO_SELFTEST)
QEMU_OBJ := $(QEMU_SRC:%.c=$(QEMU_B)/%.o)

$(QEMU_B)/%.o: %.c $(QEMU_HDR)
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(QEMU_CFLAGS) -c $< -o $@

# newlib supplies only memcpy/memset/memmove here (make cross proves the
# library needs nothing else); libgcc the 64-bit integer helpers.
$(QEMU_ELF): $(QEMU_OBJ) $(QEMU_DIR)/mps2_an385.ld
	arm-none-eabi-gcc $(QEMU_CPU) -nostdlib -T $(QEMU_DIR)/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-Map=$(QEMU_B)/it2n-m3.map -o $@ $(QEMU_OBJ) -lc -lgcc
	arm-none-eabi-size $@

.PHONY: qemu-m3
qemu-m3: $(QEMU_ELF)
	$(QEMU_DIR)/run.sh $< $(QEMU_TIMEOUT)

TEST_TARGETS += qemu-m3
