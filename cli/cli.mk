# cli/: two programs over one shared front end.
#   cli/common/   what both use: option values, the CSV reader, plot and
#                 export (cli.h, csv.h)
#   cli/it2n/     it2n: reads CSV, calls firmware_core, prints CSV
#   cli/it2nctl/  it2nctl: the same output from a running it2nd
# Each is built normally for use and with $(SAN_FLAGS) for the tests.
CLI_COMMON_SRC := $(wildcard cli/common/*.c)
CLI_HDR := $(wildcard cli/common/*.h cli/it2n/*.h)
CLI_INC := -Icli/common
CLI_SRC := $(wildcard cli/it2n/*.c)
CLI_BIN := $(BUILD)/host/it2n
CLI_SAN_BIN := $(BUILD)/san/it2n
CLI_COMMON_OBJ := $(CLI_COMMON_SRC:%.c=$(BUILD)/host/%.o)
CLI_COMMON_SAN_OBJ := $(CLI_COMMON_SRC:%.c=$(BUILD)/san/%.o)
CLI_OBJ := $(CLI_SRC:%.c=$(BUILD)/host/%.o) $(CLI_COMMON_OBJ)
CLI_SAN_OBJ := $(CLI_SRC:%.c=$(BUILD)/san/%.o) $(CLI_COMMON_SAN_OBJ)
# The reusable CSV reader, for tests and the daemon.
CLI_CSV_OBJ := $(BUILD)/host/cli/common/csv.o
CLI_CSV_SAN_OBJ := $(BUILD)/san/cli/common/csv.o

ALL_TARGETS += $(CLI_BIN)
INSTALL_TARGETS += install-cli

# cli/common and cli/it2n (the it2nctl rule below is the more specific).
$(BUILD)/host/cli/%.o: cli/%.c $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(CLI_INC) -c $< -o $@

$(BUILD)/san/cli/%.o: cli/%.c $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) $(CLI_INC) -c $< -o $@

$(CLI_BIN): $(CLI_OBJ) $(CORE_LIB)
	$(CC) $(HOST_CFLAGS) -o $@ $(CLI_OBJ) $(CORE_LIB)

$(CLI_SAN_BIN): $(CLI_SAN_OBJ) $(CORE_SAN_LIB)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -o $@ $(CLI_SAN_OBJ) $(CORE_SAN_LIB)

# it2nctl: client for a running it2nd (Modbus via libmodbus, the framing
# protocol via protocol/). Links the shared front end (cli/common/).
# The register map and its codecs: the regmap library (regmap/regmap.mk).
CTL_SRC := $(wildcard cli/it2nctl/*.c)
CTL_HDR := $(wildcard cli/it2nctl/*.h) $(CLI_HDR) $(REGMAP_HDR)
# it2nctl spb (ctl_spb.c): libmosquitto, and the Sparkplug payload code
# protoc-c generates from daemon/spb.proto (daemon/daemon.mk).
CTL_CFLAGS := $(HOST_CFLAGS) $(CLI_INC) -Icli/it2nctl $(REGMAP_INC) -I$(BUILD)/daemon \
              $(shell pkg-config --cflags libmodbus libmosquitto libprotobuf-c 2>/dev/null)
CTL_LIBS := $(shell pkg-config --libs libmodbus libmosquitto libprotobuf-c 2>/dev/null) -lm
CTL_BIN := $(BUILD)/host/it2nctl
CTL_SAN_BIN := $(BUILD)/san/it2nctl
CTL_OBJ := $(CTL_SRC:%.c=$(BUILD)/host/%.o) $(BUILD)/host/daemon/spb.pb-c.o
CTL_SAN_OBJ := $(CTL_SRC:%.c=$(BUILD)/san/%.o) $(BUILD)/san/daemon/spb.pb-c.o
# The shared front end it2nctl links.
CTL_CLI_OBJ := $(CLI_COMMON_OBJ)
CTL_CLI_SAN_OBJ := $(CLI_COMMON_SAN_OBJ)
ALL_TARGETS += $(CTL_BIN)

$(BUILD)/host/cli/it2nctl/ctl_spb.o $(BUILD)/san/cli/it2nctl/ctl_spb.o: $(BUILD)/daemon/spb.pb-c.h

$(BUILD)/host/cli/it2nctl/%.o: cli/it2nctl/%.c $(CTL_HDR) $(CORE_HDR) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(CTL_CFLAGS) -c $< -o $@

$(BUILD)/san/cli/it2nctl/%.o: cli/it2nctl/%.c $(CTL_HDR) $(CORE_HDR) $(PROTO_HDR)
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
	install -m 0644 cli/it2n/it2n.1 $(DESTDIR)$(PREFIX)/share/man/man1/it2n.1
	install -m 0755 $(CTL_BIN) $(DESTDIR)$(PREFIX)/bin/it2nctl
	install -m 0644 cli/it2nctl/it2nctl.1 $(DESTDIR)$(PREFIX)/share/man/man1/it2nctl.1

demo: $(CLI_BIN) ## Print the paper model's memberships at a few parameters
	$(CLI_BIN) eval examples/paper_4x4.csv --summary \
	  --at 0,0 --at 0.25,0.75 --at 0.5,0.5 --at 1,1

# The README's pictures of the paper example, drawn by `it2n plot` (gnuplot).
# tests/cli: cli-plot checks the committed files are still valid images
# of this size (bytes vary with the gnuplot and cairo versions).
CLI_FIGURES := docs/img/paper_T.png docs/img/paper_band_T.png
.PHONY: figures
figures: $(CLI_BIN) ## Regenerate docs/img/*.png (the paper example drawn by it2n plot)
	@mkdir -p docs/img
	$(CLI_BIN) plot examples/paper_4x4.csv --membership T -o docs/img/paper_T.png
	$(CLI_BIN) plot examples/paper_4x4.csv --interval --membership T \
	  -o docs/img/paper_band_T.png

# --version prints VERSION (-DIT2N_VERSION, cli/common/cli.h): every object
# of the two programs is rebuilt when it changes.
$(CLI_OBJ) $(CLI_SAN_OBJ) $(CTL_SRC:%.c=$(BUILD)/host/%.o) $(CTL_SRC:%.c=$(BUILD)/san/%.o): VERSION
