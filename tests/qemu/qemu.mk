# tests/qemu/: the core test vectors and the protocol self-test
# (protocol/it2n_selftest.c) on emulated Cortex-M parts, semihosting:
#   qemu-system-arm -M mps2-an385 -semihosting-config enable=on,target=native
# Freestanding image: startup.c (vectors, reset), mps2_an385.ld, semihost.c.
# The model structs live in .bss (4 MB SSRAM), the 64 KB stack below them.
# Images: m3  Cortex-M3 code on mps2-an385 (the required run),
#         m0p Cortex-M0+ (ARMv6-M, no divider) code on the same M3 machine:
#             ARMv6-M is a subset of ARMv7-M, and qemu has no M0+ board with
#             enough RAM for the models,
#         m4  Cortex-M4 code on mps2-an386 (same memory map).
QEMU_DIR := tests/qemu
QEMU_TIMEOUT ?= 120
QEMU_SRC := $(CORE_SRC) $(PROTO_SRC) \
            tests/vectors/core_vectors.c tests/vectors/vec_scenarios.c tests/vectors/vec_paper.c \
            $(QEMU_DIR)/main.c $(QEMU_DIR)/startup.c $(QEMU_DIR)/semihost.c
QEMU_HDR := $(wildcard firmware_core/*.h protocol/*.h protocol/*.inc tests/vectors/*.h $(QEMU_DIR)/*.h)
QEMU_CFLAGS := -ffreestanding -std=c99 -Os -g $(CORE_WARN) \
               -ffunction-sections -fdata-sections \
               -Ifirmware_core -Iprotocol -Itests/vectors -I$(QEMU_DIR) -DIT2N_HAVE_PROTO_SELFTEST

QEMU_VARIANTS := m3 m0p m4
QEMU_CPU_m3  := -mcpu=cortex-m3 -mthumb
QEMU_CPU_m0p := -mcpu=cortex-m0plus -mthumb
QEMU_CPU_m4  := -mcpu=cortex-m4 -mthumb
QEMU_MACHINE_m3  := mps2-an385
QEMU_MACHINE_m0p := mps2-an385
QEMU_MACHINE_m4  := mps2-an386

# newlib supplies only memcpy/memset/memmove here (make cross proves the
# library needs nothing else); libgcc the 64-bit integer helpers.
define QEMU_IMAGE_RULES
QEMU_B_$(1) := $(BUILD)/qemu-$(1)
QEMU_OBJ_$(1) := $$(QEMU_SRC:%.c=$(BUILD)/qemu-$(1)/%.o)

$(BUILD)/qemu-$(1)/%.o: %.c $$(QEMU_HDR)
	@mkdir -p $$(@D)
	arm-none-eabi-gcc $(QEMU_CPU_$(1)) $$(QEMU_CFLAGS) -c $$< -o $$@

$(BUILD)/qemu-$(1)/it2n-$(1).elf: $$(QEMU_OBJ_$(1)) $(QEMU_DIR)/mps2_an385.ld
	arm-none-eabi-gcc $(QEMU_CPU_$(1)) -nostdlib -T $(QEMU_DIR)/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-Map=$(BUILD)/qemu-$(1)/it2n-$(1).map -o $$@ $$(QEMU_OBJ_$(1)) -lc -lgcc

.PHONY: qemu-$(1)
qemu-$(1): $(BUILD)/qemu-$(1)/it2n-$(1).elf
	$(QEMU_DIR)/run.sh $$< $(QEMU_MACHINE_$(1)) $(QEMU_TIMEOUT)
endef
$(foreach v,$(QEMU_VARIANTS),$(eval $(call QEMU_IMAGE_RULES,$(v))))

TEST_TARGETS += $(QEMU_VARIANTS:%=qemu-%)
