# cli/: the host command-line tool `it2n` (reads CSV, calls firmware_core,
# prints CSV). Built normally for use and with $(SAN_FLAGS) for the tests.
CLI_SRC := $(filter-out cli/ctl%.c,$(wildcard cli/*.c))
CLI_HDR := $(filter-out cli/ctl%.h,$(wildcard cli/*.h))
CLI_BIN := $(BUILD)/host/it2n
CLI_SAN_BIN := $(BUILD)/san/it2n
CLI_OBJ := $(CLI_SRC:%.c=$(BUILD)/host/%.o)
CLI_SAN_OBJ := $(CLI_SRC:%.c=$(BUILD)/san/%.o)
# The reusable CSV reader, for tests and the daemon.
CLI_CSV_OBJ := $(BUILD)/host/cli/csv.o
CLI_CSV_SAN_OBJ := $(BUILD)/san/cli/csv.o

ALL_TARGETS += $(CLI_BIN)
INSTALL_TARGETS += install-cli

$(BUILD)/host/cli/%.o: cli/%.c $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -Icli -c $< -o $@

$(BUILD)/san/cli/%.o: cli/%.c $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -Icli -c $< -o $@

$(CLI_BIN): $(CLI_OBJ) $(CORE_LIB)
	$(CC) $(HOST_CFLAGS) -o $@ $(CLI_OBJ) $(CORE_LIB)

$(CLI_SAN_BIN): $(CLI_SAN_OBJ) $(CORE_SAN_LIB)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -o $@ $(CLI_SAN_OBJ) $(CORE_SAN_LIB)

# it2nctl: client for a running it2nd (Modbus via libmodbus, the framing
# protocol via protocol/). Links the CLI's CSV reader, plot and output code.
# The register map and its codecs: the regmap library (regmap/regmap.mk).
CTL_SRC := $(wildcard cli/ctl*.c)
CTL_HDR := $(wildcard cli/ctl*.h) $(CLI_HDR) $(REGMAP_HDR)
# it2nctl spb (ctl_spb.c): libmosquitto, and the Sparkplug payload code
# protoc-c generates from daemon/spb.proto (daemon/daemon.mk).
CTL_CFLAGS := $(HOST_CFLAGS) -Icli $(REGMAP_INC) -I$(BUILD)/daemon \
              $(shell pkg-config --cflags libmodbus libmosquitto libprotobuf-c 2>/dev/null)
CTL_LIBS := $(shell pkg-config --libs libmodbus libmosquitto libprotobuf-c 2>/dev/null) -lm
CTL_BIN := $(BUILD)/host/it2nctl
CTL_SAN_BIN := $(BUILD)/san/it2nctl
CTL_OBJ := $(CTL_SRC:%.c=$(BUILD)/host/%.o) $(BUILD)/host/daemon/spb.pb-c.o
CTL_SAN_OBJ := $(CTL_SRC:%.c=$(BUILD)/san/%.o) $(BUILD)/san/daemon/spb.pb-c.o
# it2n's modules it2nctl reuses (everything but its main).
CTL_CLI_OBJ := $(filter-out $(BUILD)/host/cli/main.o,$(CLI_OBJ))
CTL_CLI_SAN_OBJ := $(filter-out $(BUILD)/san/cli/main.o,$(CLI_SAN_OBJ))
ALL_TARGETS += $(CTL_BIN)

$(BUILD)/host/cli/ctl_spb.o $(BUILD)/san/cli/ctl_spb.o: $(BUILD)/daemon/spb.pb-c.h

$(BUILD)/host/cli/ctl%.o: cli/ctl%.c $(CTL_HDR) $(CORE_HDR) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(CTL_CFLAGS) -c $< -o $@

$(BUILD)/san/cli/ctl%.o: cli/ctl%.c $(CTL_HDR) $(CORE_HDR) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(CTL_CFLAGS) $(SAN_FLAGS) -c $< -o $@

$(CTL_BIN): $(CTL_OBJ) $(CTL_CLI_OBJ) $(REGMAP_LIB) $(PROTO_LIB) $(CORE_LIB)
	$(CC) $(HOST_CFLAGS) -o $@ $(CTL_OBJ) $(CTL_CLI_OBJ) $(REGMAP_LIB) $(PROTO_LIB) \
	  $(CORE_LIB) $(CTL_LIBS)

$(CTL_SAN_BIN): $(CTL_SAN_OBJ) $(CTL_CLI_SAN_OBJ) $(REGMAP_SAN_LIB) $(PROTO_SAN_LIB) $(CORE_SAN_LIB)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -o $@ $(CTL_SAN_OBJ) $(CTL_CLI_SAN_OBJ) \
	  $(REGMAP_SAN_LIB) $(PROTO_SAN_LIB) $(CORE_SAN_LIB) $(CTL_LIBS)

.PHONY: install-cli demo
install-cli: $(CLI_BIN) $(CTL_BIN)
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/share/man/man1
	install -m 0755 $(CLI_BIN) $(DESTDIR)$(PREFIX)/bin/it2n
	install -m 0644 cli/it2n.1 $(DESTDIR)$(PREFIX)/share/man/man1/it2n.1
	install -m 0755 $(CTL_BIN) $(DESTDIR)$(PREFIX)/bin/it2nctl
	install -m 0644 cli/it2nctl.1 $(DESTDIR)$(PREFIX)/share/man/man1/it2nctl.1

demo: $(CLI_BIN) ## Print the paper model's memberships at a few parameters
	$(CLI_BIN) eval examples/paper_4x4.csv --summary \
	  --at 0,0 --at 0.25,0.75 --at 0.5,0.5 --at 1,1

# The README's pictures of the paper example, drawn by `it2n plot` (gnuplot).
# tests/cli: cli-test-plot checks the committed files are still valid images
# of this size (bytes vary with the gnuplot and cairo versions).
CLI_FIGURES := docs/img/paper_T.png docs/img/paper_band_T.png
.PHONY: figures
figures: $(CLI_BIN) ## Regenerate docs/img/*.png (the paper example drawn by it2n plot)
	@mkdir -p docs/img
	$(CLI_BIN) plot examples/paper_4x4.csv --membership T -o docs/img/paper_T.png
	$(CLI_BIN) plot examples/paper_4x4.csv --interval --membership T \
	  -o docs/img/paper_band_T.png
