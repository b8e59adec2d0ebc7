# protocol/: serial framing protocol (portable C99, same rules as the core):
# what an instrument needs. (The Modbus register map is a library of its own:
# regmap/.)
# Exports PROTO_SRC, PROTO_LIB, PROTO_SAN_LIB for the daemon and cross build.
# Tests, fuzzer and the example instrument live here too (one fragment).
PROTO_SRC := $(wildcard protocol/*.c)
PROTO_HDR := $(wildcard protocol/*.h) protocol/it2n_vectors.inc $(CORE_HDR)
PROTO_OBJ := $(PROTO_SRC:%.c=$(BUILD)/host/%.o)
PROTO_LIB := $(BUILD)/host/libit2n_proto.a
PROTO_SAN_OBJ := $(PROTO_SRC:%.c=$(BUILD)/san/%.o)
PROTO_SAN_LIB := $(BUILD)/san/libit2n_proto.a
FUZZ_SECONDS ?= 60

ALL_TARGETS += $(PROTO_LIB)
ifneq ($(wildcard examples/instrument/*.c),)
ALL_TARGETS += $(BUILD)/host/it2n-instrument
endif

$(BUILD)/host/protocol/%.o: protocol/%.c $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) -c $< -o $@

$(BUILD)/san/protocol/%.o: protocol/%.c $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) $(SAN_FLAGS) -c $< -o $@

$(PROTO_LIB): $(PROTO_OBJ)
	@rm -f $@; ar rcs $@ $^

$(PROTO_SAN_LIB): $(PROTO_SAN_OBJ)
	@rm -f $@; ar rcs $@ $^

# ---- tests (tests/protocol/) ---------------------------------------------
PROTO_T := tests/protocol
PROTO_TB := $(BUILD)/tests/protocol
PROTO_TESTS := test_proto test_msg test_link test_inst test_reboot test_vectors lossy fuzz_plain
PROTO_THDR := $(wildcard $(PROTO_T)/*.h)

$(PROTO_TB)/%: $(PROTO_T)/%.c $(PROTO_THDR) $(PROTO_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -I$(PROTO_T) $< -o $@ $(PROTO_LIB) -lcmocka

$(PROTO_TB)/san/%: $(PROTO_T)/%.c $(PROTO_THDR) $(PROTO_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -I$(PROTO_T) $< -o $@ $(PROTO_SAN_LIB) -lcmocka

$(PROTO_TB)/fuzz_plain: $(PROTO_T)/fuzz_proto.c $(PROTO_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -DIT2N_FUZZ_MAIN $< -o $@ $(PROTO_LIB)

$(PROTO_TB)/san/fuzz_plain: $(PROTO_T)/fuzz_proto.c $(PROTO_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -DIT2N_FUZZ_MAIN $< -o $@ $(PROTO_SAN_LIB)

PROTO_TEST_BINS := $(PROTO_TESTS:%=$(PROTO_TB)/%) $(PROTO_TESTS:%=$(PROTO_TB)/san/%)

.PHONY: proto-test proto-cppcheck proto-fuzz proto-vectors
TEST_TARGETS += proto-test proto-cppcheck

# Unit, golden vector, lossy-channel and fixed-corpus fuzz runs, each built
# normally and with ASan+UBSan.
proto-test: $(PROTO_TEST_BINS)
	@set -e; for t in $(PROTO_TESTS); do \
	  for b in $(PROTO_TB)/$$t $(PROTO_TB)/san/$$t; do \
	    echo "== $$b"; $$b $(PROTO_T)/corpus protocol/vectors; done; done
	python3 $(PROTO_T)/check_vectors.py protocol/vectors

proto-cppcheck:
	cppcheck --std=c99 --enable=warning,portability --error-exitcode=1 -q \
	  -Ifirmware_core -Iprotocol protocol/

# Regenerate protocol/vectors/*.hex and protocol/it2n_vectors.inc from the
# message table (only after an intended wire change; review the diff).
proto-vectors: $(PROTO_TB)/gen_vectors ## Regenerate protocol/vectors/ after an intended wire change
	$(PROTO_TB)/gen_vectors protocol/vectors protocol/it2n_vectors.inc $(PROTO_T)/corpus
	python3 $(PROTO_T)/check_vectors.py --update-doc protocol/vectors

# End to end: the example instrument over a lossy pty against a receiver
# built from the link and the core (needs the core library).
PROTO_E2E_DEPS := $(PROTO_T)/test_instrument.c examples/instrument/synth.c \
  examples/instrument/synth.h $(PROTO_THDR)
$(PROTO_TB)/e2e/test_instrument: $(PROTO_E2E_DEPS) $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -I$(PROTO_T) -Iexamples/instrument $(PROTO_T)/test_instrument.c \
	  examples/instrument/synth.c -o $@ $(PROTO_LIB) $(CORE_LIB) -lcmocka

$(PROTO_TB)/e2e/san/test_instrument: $(PROTO_E2E_DEPS) $(PROTO_SAN_LIB) $(CORE_SAN_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -I$(PROTO_T) -Iexamples/instrument $(PROTO_T)/test_instrument.c \
	  examples/instrument/synth.c -o $@ $(PROTO_SAN_LIB) $(CORE_SAN_LIB) -lcmocka

.PHONY: proto-e2e
TEST_TARGETS += proto-e2e
proto-e2e: $(PROTO_TB)/e2e/test_instrument $(PROTO_TB)/e2e/san/test_instrument $(BUILD)/host/it2n-instrument
	$(PROTO_TB)/e2e/test_instrument $(BUILD)/host/it2n-instrument
	$(PROTO_TB)/e2e/san/test_instrument $(BUILD)/host/it2n-instrument

# ---- libFuzzer (clang) ----------------------------------------------------
PROTO_FUZZ := $(BUILD)/fuzz/proto_fuzz
FUZZ_TARGETS += proto-fuzz

$(PROTO_FUZZ): $(PROTO_T)/fuzz_proto.c $(PROTO_SRC) $(PROTO_HDR)
	@mkdir -p $(@D)
	clang -std=c11 -g -O1 -fsanitize=fuzzer,address,undefined \
	  -Ifirmware_core -Iprotocol $(PROTO_T)/fuzz_proto.c $(PROTO_SRC) -o $@

proto-fuzz: $(PROTO_FUZZ)
	@mkdir -p $(BUILD)/fuzz/proto_corpus
	$(PROTO_FUZZ) -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 \
	  $(BUILD)/fuzz/proto_corpus $(PROTO_T)/corpus

# ---- example instrument ---------------------------------------------------
PROTO_INSTR_SRC := $(wildcard examples/instrument/*.c)
$(BUILD)/host/it2n-instrument: $(PROTO_INSTR_SRC) $(wildcard examples/instrument/*.h) $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -Iexamples/instrument $(PROTO_INSTR_SRC) -o $@ $(PROTO_LIB) $(CORE_LIB)
