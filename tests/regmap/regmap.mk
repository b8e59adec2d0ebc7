# tests/regmap/: the register map library (regmap/).
#   regmap-unit  codecs against golden bytes and a 128-bit reference, the
#                table's invariants (cmocka; host and ASan+UBSan builds)
#   regmap-doc   docs/registers.md is exactly what gen_registers prints
RM_T := tests/regmap
RM_TB := $(BUILD)/tests/regmap

$(RM_TB)/test_regmap: $(RM_T)/test_regmap.c $(REGMAP_HDR) $(REGMAP_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(REGMAP_INC) $< -o $@ $(REGMAP_LIB) -lcmocka

$(RM_TB)/san/test_regmap: $(RM_T)/test_regmap.c $(REGMAP_HDR) $(REGMAP_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) $(REGMAP_INC) $< -o $@ $(REGMAP_SAN_LIB) -lcmocka

.PHONY: regmap-unit regmap-doc
TEST_TARGETS += regmap-unit regmap-doc

regmap-unit: $(RM_TB)/test_regmap $(RM_TB)/san/test_regmap
	$(RM_TB)/test_regmap
	$(RM_TB)/san/test_regmap

regmap-doc: $(GEN_REGISTERS)
	@$(GEN_REGISTERS) | diff -u docs/registers.md - || \
	  { echo "docs/registers.md is stale: run 'make docs/registers.md'" >&2; exit 1; }
	@echo "docs/registers.md is current"
