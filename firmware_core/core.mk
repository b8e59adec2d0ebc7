# firmware_core: portable fixed-point library.
CORE_SRC := $(call src_list,firmware_core)
CORE_HDR := $(wildcard firmware_core/*.h)
CORE_OBJ := $(CORE_SRC:%.c=$(BUILD)/host/%.o)
CORE_LIB := $(BUILD)/host/libit2n.a
CORE_SAN_OBJ := $(CORE_SRC:%.c=$(BUILD)/san/%.o)
CORE_SAN_LIB := $(BUILD)/san/libit2n.a

ALL_TARGETS += $(CORE_LIB)

$(BUILD)/host/firmware_core/%.o: firmware_core/%.c $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) -c $< -o $@

$(BUILD)/san/firmware_core/%.o: firmware_core/%.c $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) $(SAN_FLAGS) '-DIT2N_ASSERT(c)=((c) ? (void)0 : __builtin_trap())' -c $< -o $@

$(CORE_LIB): $(CORE_OBJ)
	@rm -f $@; ar rcs $@ $^

$(CORE_SAN_LIB): $(CORE_SAN_OBJ)
	@rm -f $@; ar rcs $@ $^

# The uniform inverse tables are generated (exact rationals) and checked in:
# a firmware build needs no Python. core-tables-check (tests/core/core.mk)
# regenerates and compares.
.PHONY: core-tables
core-tables: ## Regenerate firmware_core/it2n_uniform_inv.c
	/usr/bin/python3 firmware_core/gen/gen_uniform_inv.py > firmware_core/it2n_uniform_inv.c
