# protocol/: serial framing protocol (portable C99, same rules as the core):
# what an instrument needs. (The Modbus register map is a library of its own:
# regmap/.)
# Exports PROTO_SRC, PROTO_HDR, PROTO_LIB, PROTO_SAN_LIB for the daemon, the
# cross build and the tests (tests/protocol/protocol.mk), and builds the
# example instrument (examples/instrument/).
PROTO_SRC := $(call src_list,protocol)
PROTO_HDR := $(wildcard protocol/*.h) protocol/it2n_vectors.inc $(CORE_HDR)
PROTO_OBJ := $(PROTO_SRC:%.c=$(BUILD)/host/%.o)
PROTO_LIB := $(BUILD)/host/libit2n_proto.a
PROTO_SAN_OBJ := $(PROTO_SRC:%.c=$(BUILD)/san/%.o)
PROTO_SAN_LIB := $(BUILD)/san/libit2n_proto.a

ALL_TARGETS += $(PROTO_LIB) $(BUILD)/host/it2n-instrument

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

# ---- example instrument ---------------------------------------------------
PROTO_INSTR_SRC := $(wildcard examples/instrument/*.c)
$(BUILD)/host/it2n-instrument: $(PROTO_INSTR_SRC) $(wildcard examples/instrument/*.h) $(PROTO_LIB) $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -Iexamples/instrument $(PROTO_INSTR_SRC) -o $@ $(PROTO_LIB) $(CORE_LIB)
