# regmap/: the Modbus register map as a library of its own (portable C99,
# no heap, no state, no I/O, no transport): the register table, its
# lookups and the value codecs (word orders, float32, scaled integers).
# The daemon serves it, it2nctl and the PLC simulator read it, and
# gen_registers prints docs/registers.md from it. Nothing outside daemon/
# reaches into daemon/ for it (lint checks: tests/lint/layers.py).
# Exports REGMAP_INC, REGMAP_HDR, REGMAP_LIB, REGMAP_SAN_LIB, GEN_REGISTERS.
REGMAP_SRC := $(call src_list,regmap)
REGMAP_HDR := $(wildcard regmap/*.h)
REGMAP_INC := -Iregmap
REGMAP_OBJ := $(REGMAP_SRC:%.c=$(BUILD)/host/%.o)
REGMAP_SAN_OBJ := $(REGMAP_SRC:%.c=$(BUILD)/san/%.o)
REGMAP_LIB := $(BUILD)/host/libit2n_regmap.a
REGMAP_SAN_LIB := $(BUILD)/san/libit2n_regmap.a
GEN_REGISTERS := $(BUILD)/host/gen_registers

ALL_TARGETS += $(REGMAP_LIB) $(GEN_REGISTERS)

# The core's rules: strict C99, warnings (with -Wconversion) as errors.
$(BUILD)/host/regmap/%.o: regmap/%.c $(REGMAP_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) $(REGMAP_INC) -c $< -o $@

$(BUILD)/san/regmap/%.o: regmap/%.c $(REGMAP_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) $(SAN_FLAGS) $(REGMAP_INC) -c $< -o $@

$(REGMAP_LIB): $(REGMAP_OBJ)
	@rm -f $@; ar rcs $@ $^

$(REGMAP_SAN_LIB): $(REGMAP_SAN_OBJ)
	@rm -f $@; ar rcs $@ $^

# docs/registers.md is generated from the table (regmap/it2n_regmap.c).
$(GEN_REGISTERS): regmap/tools/gen_registers.c $(REGMAP_HDR) $(REGMAP_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(REGMAP_INC) $< -o $@ $(REGMAP_LIB)

docs/registers.md: $(GEN_REGISTERS)
	$(GEN_REGISTERS) > $@.tmp && mv $@.tmp $@
