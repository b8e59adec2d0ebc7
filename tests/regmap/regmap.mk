# tests/regmap/: the register map library (regmap/).
#   regmap-unit  codecs against golden bytes and a 128-bit reference, the
#                table's invariants (cmocka; host and ASan+UBSan builds, and the
#                codec's SSE2 path without its AVX2 one)
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

# The codec's SSE2 path too where the CPU has AVX2 (the library picks
# AVX2 at run time; -DIT2N_NO_AVX2 leaves it out): the same tests.
$(RM_TB)/sse2/it2n_regmap_codec.o: regmap/it2n_regmap_codec.c $(REGMAP_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) -DIT2N_NO_AVX2 $(REGMAP_INC) -c $< -o $@

$(RM_TB)/sse2/test_regmap: $(RM_T)/test_regmap.c $(RM_TB)/sse2/it2n_regmap_codec.o $(REGMAP_HDR) $(REGMAP_LIB)
	$(CC) $(HOST_CFLAGS) $(REGMAP_INC) $< $(RM_TB)/sse2/it2n_regmap_codec.o -o $@ $(REGMAP_LIB) -lcmocka

regmap-unit: $(RM_TB)/test_regmap $(RM_TB)/san/test_regmap $(RM_TB)/sse2/test_regmap
	$(RM_TB)/test_regmap
	$(RM_TB)/san/test_regmap
	$(RM_TB)/sse2/test_regmap

regmap-doc: $(GEN_REGISTERS)
	@$(GEN_REGISTERS) | diff -u docs/registers.md - || \
	  { echo "docs/registers.md is stale: run 'make docs/registers.md'" >&2; exit 1; }
	@echo "docs/registers.md is current"
