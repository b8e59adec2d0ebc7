# tests/fuzz_daemon: fuzzers for every parser of untrusted input in it2nd —
# Modbus TCP (MBAP framing + request handling), Modbus RTU framing, the WAL
# and snapshot files (store_open recovery), the INI config (conf_load) and
# the instrument links' message handling (links.c).
# The daemon's own sources are compiled here with the harness; loop.c and
# log.c are replaced by tests/fuzz_daemon/fake_env.c (fake clock, handlers
# called by hand). Each target builds three ways:
#   $(FZD_B)/X       gcc, plain corpus run (fuzz_main.c)      make test
#   $(FZD_B)/san/X   the same with ASan+UBSan                 make test
#   $(BUILD)/fuzz/fuzzd_X  clang libFuzzer+ASan+UBSan         make fuzz
FZD := tests/fuzz_daemon
FZD_B := $(BUILD)/tests/fuzz_daemon
FZD_TARGETS := modbus rtu store conf links spbcmd spbsf
FZD_PAPER := $(BUILD)/daemon/paper_data.c
FZD_PKGS := $(shell pkg-config --cflags --libs libmodbus inih 2>/dev/null) -lm
# No pending findings: every check of the harnesses is on (the FZD_STRICT
# switch that pinned open findings 6-9 went with their fixes; see
# docs/security.md, "Findings").
FZD_DEFS :=
FZD_CFLAGS := $(HOST_CFLAGS) -Idaemon $(REGMAP_INC) -I$(BUILD)/daemon -I$(FZD) $(FZD_DEFS)
FZD_HDR := $(wildcard $(FZD)/*.h daemon/*.h) $(REGMAP_HDR) $(CORE_HDR) $(wildcard protocol/*.h)
FZD_COMMON := $(FZD)/fake_env.c
FZD_MB := daemon/mb_req.c daemon/mb_map.c $(REGMAP_SRC) daemon/models.c daemon/store.c daemon/snapshot.c daemon/errs.c $(FZD_PAPER)
FZD_SRC_modbus := daemon/mb_tcp.c daemon/acl.c daemon/porthint.c $(FZD_MB)
# conf: what a reload compares a port's or a link's section with (conf_rtu_same,
# conf_link_same) lives with the parser.
FZD_CONF := daemon/conf.c daemon/conf_schema.c daemon/acl.c daemon/spb_conf.c
FZD_SRC_rtu := daemon/mb_rtu.c daemon/link_serial.c $(FZD_MB) $(FZD_CONF)
FZD_SRC_store := daemon/store.c daemon/models.c $(wildcard daemon/snapshot.c) daemon/errs.c $(FZD_PAPER)
FZD_SRC_conf := $(FZD_CONF)
# conf: a dictionary of the schema's section headers, "key = " and words
# (tests/fuzz_daemon/conf_dict.c), for libFuzzer (-dict=) and the plain
# driver's token insertions (FUZZ_DICT).
FZD_DICT_conf := $(FZD_B)/conf.dict
FZD_SRC_links := daemon/links.c daemon/link_serial.c daemon/models.c daemon/store.c $(wildcard daemon/snapshot.c) daemon/errs.c \
  $(FZD_PAPER) $(FZD_CONF)
# spbcmd: the Sparkplug NCMD/DCMD payload decoder (daemon/spb_payload.c and
# the protoc-c code of daemon/spb.proto).
FZD_SRC_spbcmd := daemon/spb_payload.c $(SPB_PB_C)
FZD_LD_spbcmd := -lprotobuf-c
# spbsf: the store-and-forward file of the Sparkplug node (daemon/spb_sf.c).
FZD_SRC_spbsf := daemon/spb_sf.c
FZD_SECONDS ?= $(FUZZ_SECONDS)
# links: the harness takes the daemon's write()s to the link (fuzz_links.c).
FZD_LD_links := -Wl,--wrap=write

# The gcc builds (make test) link the daemon's own objects, the ones it2nd
# and the daemon's unit tests link (same flags: DAEMON_CFLAGS is FZD_CFLAGS
# but for the harness's include directory), instead of compiling the same
# sources again for each of the 14 programs; the regmap sources come from
# its library. FZD_OBJ(target, object directory).
FZD_OBJ = $(patsubst daemon/%.c,$(2)/daemon/%.o,$(patsubst $(BUILD)/daemon/%.c,$(2)/daemon/%.o,\
  $(filter-out $(REGMAP_SRC),$(FZD_SRC_$(1)))))

define FZD_RULES
$(FZD_B)/fuzz_$(1): $(FZD)/fuzz_$(1).c $(FZD)/fuzz_main.c $(FZD_COMMON) $(call FZD_OBJ,$(1),$(BUILD)/host) $(FZD_HDR) \
  $(REGMAP_LIB) $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $$(@D)
	$(CC) $(FZD_CFLAGS) -o $$@ $(FZD)/fuzz_$(1).c $(FZD)/fuzz_main.c $(FZD_COMMON) \
	  $(call FZD_OBJ,$(1),$(BUILD)/host) $(REGMAP_LIB) $(PROTO_LIB) $(CORE_LIB) $(FZD_PKGS) $(FZD_LD_$(1))

$(FZD_B)/san/fuzz_$(1): $(FZD)/fuzz_$(1).c $(FZD)/fuzz_main.c $(FZD_COMMON) $(call FZD_OBJ,$(1),$(BUILD)/san) $(FZD_HDR) \
  $(REGMAP_SAN_LIB) $(PROTO_SAN_LIB) $(CORE_SAN_LIB)
	@mkdir -p $$(@D)
	$(CC) $(FZD_CFLAGS) $(SAN_FLAGS) -o $$@ $(FZD)/fuzz_$(1).c $(FZD)/fuzz_main.c $(FZD_COMMON) \
	  $(call FZD_OBJ,$(1),$(BUILD)/san) $(REGMAP_SAN_LIB) $(PROTO_SAN_LIB) $(CORE_SAN_LIB) $(FZD_PKGS) $(FZD_LD_$(1))

$(BUILD)/fuzz/fuzzd_$(1): $(FZD)/fuzz_$(1).c $(FZD_COMMON) $(FZD_SRC_$(1)) $(FZD_HDR) $(CORE_SRC) $(PROTO_SRC)
	@mkdir -p $$(@D)
	clang -std=c11 -D_GNU_SOURCE -O1 -g -fsanitize=fuzzer,address,undefined \
	  -Ifirmware_core -Iprotocol -Idaemon $(REGMAP_INC) -I$(BUILD)/daemon -I$(FZD) $(FZD_DEFS) -o $$@ $(FZD)/fuzz_$(1).c \
	  $(FZD_COMMON) $(FZD_SRC_$(1)) $(CORE_SRC) $(PROTO_SRC) $(FZD_PKGS) $(FZD_LD_$(1))

.PHONY: fuzzd-fuzz-$(1)
fuzzd-fuzz-$(1): $(BUILD)/fuzz/fuzzd_$(1) $(FZD_DICT_$(1))
	@rm -rf $(BUILD)/fuzz/fuzzd_$(1)_corpus; mkdir -p $(BUILD)/fuzz/fuzzd_$(1)_corpus
	$(BUILD)/fuzz/fuzzd_$(1) -max_total_time=$(FZD_SECONDS) -timeout=10 -print_final_stats=1 \
	  -artifact_prefix=$(BUILD)/fuzz/fuzzd_$(1)- $(if $(FZD_DICT_$(1)),-dict=$(FZD_DICT_$(1))) \
	  -max_len=$(if $(filter store,$(1)),16384,4096) $(BUILD)/fuzz/fuzzd_$(1)_corpus $(FZD)/corpus/$(1)
endef
$(foreach t,$(FZD_TARGETS),$(eval $(call FZD_RULES,$(t))))

FZD_BINS := $(FZD_TARGETS:%=$(FZD_B)/fuzz_%) $(FZD_TARGETS:%=$(FZD_B)/san/fuzz_%)

$(FZD_B)/conf_dict: $(FZD)/conf_dict.c daemon/conf_schema.c $(FZD_HDR)
	@mkdir -p $(@D)
	$(CC) $(FZD_CFLAGS) -o $@ $(FZD)/conf_dict.c daemon/conf_schema.c

$(FZD_B)/conf.dict: $(FZD_B)/conf_dict
	$< > $@.tmp && mv $@.tmp $@

.PHONY: fuzzd-corpus fuzzd-fuzz
TEST_TARGETS += fuzzd-corpus
FUZZ_TARGETS += fuzzd-fuzz

# Fixed corpus + seeded mutations, normal and sanitizer builds.
fuzzd-corpus: $(FZD_BINS) $(FZD_DICT_conf)
	@set -e; for t in $(FZD_TARGETS); do \
	  d=$$(case $$t in conf) echo $(FZD_DICT_conf);; esac); \
	  FUZZ_DICT=$$d $(FZD_B)/fuzz_$$t $(FZD)/corpus/$$t; \
	  FUZZ_DICT=$$d $(FZD_B)/san/fuzz_$$t $(FZD)/corpus/$$t; done

fuzzd-fuzz: $(FZD_TARGETS:%=fuzzd-fuzz-%)

# make lint (mk/lint.mk) runs this: cppcheck over the harnesses.
LINT_FUZZD = $(LINT_TESTS) -Idaemon $(FZD)
