# A firmware Makefile that compiles it2n from source, no install step:
# the core's and the protocol's sources and include paths, and one
# IT2N_CONFIG header for the options (library and application must agree).
#   make -f plain.mk IT2N=path/to/it2n APP=dir/of/the/application OUT=build
IT2N    ?= ../it2n
APP     ?= .
OUT     ?= build
CC      := arm-none-eabi-gcc
CPU     := -mcpu=cortex-m0plus -mthumb
CFLAGS  := $(CPU) -std=c99 -Os -ffreestanding -ffunction-sections -fdata-sections \
           -Wall -Wextra -Wpedantic -Werror \
           -I$(IT2N)/firmware_core -I$(IT2N)/protocol \
           -I$(APP) -DIT2N_CONFIG=it2n_m0p_config.h
LDFLAGS := $(CPU) -nostdlib -Wl,--gc-sections -T $(APP)/m0p.ld
IT2N_SRC := $(wildcard $(IT2N)/firmware_core/*.c) $(wildcard $(IT2N)/protocol/*.c)
APP_SRC  := $(APP)/mcu_main.c $(APP)/paper_model.c
OBJ      := $(patsubst %.c,$(OUT)/%.o,$(notdir $(APP_SRC) $(IT2N_SRC)))

vpath %.c $(APP) $(IT2N)/firmware_core $(IT2N)/protocol

$(OUT)/firmware.elf: $(OBJ)
	$(CC) $(LDFLAGS) $^ -lc -lgcc -o $@

$(OUT)/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -MMD -MP -c $< -o $@

-include $(OBJ:.o=.d)
