# daemon/: it2nd, the Linux daemon (Modbus TCP/RTU, links, persistence).
# Exports IT2ND (host build) and IT2ND_SAN (ASan+UBSan build).
DAEMON_PKGS := libmodbus liburing inih libusb-1.0 libmicrohttpd libmosquitto libprotobuf-c libssl libcrypto
DAEMON_CFLAGS := $(HOST_CFLAGS) -Idaemon $(REGMAP_INC) -I$(BUILD)/daemon $(shell pkg-config --cflags $(DAEMON_PKGS) 2>/dev/null)
DAEMON_LIBS := $(shell pkg-config --libs $(DAEMON_PKGS) 2>/dev/null) -lm -pthread
DAEMON_SRC := $(wildcard daemon/*.c)
# The Sparkplug B payload code, generated from daemon/spb.proto by protoc-c
# (docs/sparkplug.md, "Encoding").
SPB_PB_C := $(BUILD)/daemon/spb.pb-c.c
SPB_PB_H := $(BUILD)/daemon/spb.pb-c.h
DAEMON_HDR := $(wildcard daemon/*.h) $(REGMAP_HDR) $(CORE_HDR) $(wildcard protocol/it2n_*.h) $(SPB_PB_H)
DAEMON_GEN := $(BUILD)/daemon/paper_data.c
DAEMON_OBJ := $(DAEMON_SRC:%.c=$(BUILD)/host/%.o) $(BUILD)/host/daemon/paper_data.o $(BUILD)/host/daemon/spb.pb-c.o
DAEMON_SAN_OBJ := $(DAEMON_SRC:%.c=$(BUILD)/san/%.o) $(BUILD)/san/daemon/paper_data.o $(BUILD)/san/daemon/spb.pb-c.o
IT2ND := $(BUILD)/host/it2nd
IT2ND_SAN := $(BUILD)/san/it2nd

ALL_TARGETS += $(IT2ND)
INSTALL_TARGETS += install-daemon

# The paper's example data set compiled in (the CLI's CSV reader lives in cli/).
$(DAEMON_GEN): examples/paper_4x4.csv daemon/tools/csv2c.awk
	@mkdir -p $(@D)
	awk -f daemon/tools/csv2c.awk $< > $@.tmp && mv $@.tmp $@

$(BUILD)/host/daemon/paper_data.o: $(DAEMON_GEN) daemon/paper_data.h
	@mkdir -p $(@D)
	$(CC) $(DAEMON_CFLAGS) -c $< -o $@

$(BUILD)/san/daemon/paper_data.o: $(DAEMON_GEN) daemon/paper_data.h
	@mkdir -p $(@D)
	$(CC) $(DAEMON_CFLAGS) $(SAN_FLAGS) -c $< -o $@

$(SPB_PB_H): $(SPB_PB_C)
$(SPB_PB_C): daemon/spb.proto
	@mkdir -p $(@D)
	protoc-c --c_out=$(@D) -Idaemon $<

$(BUILD)/host/daemon/spb.pb-c.o: $(SPB_PB_C) $(SPB_PB_H)
	@mkdir -p $(@D)
	$(CC) $(DAEMON_CFLAGS) -c $< -o $@

$(BUILD)/san/daemon/spb.pb-c.o: $(SPB_PB_C) $(SPB_PB_H)
	@mkdir -p $(@D)
	$(CC) $(DAEMON_CFLAGS) $(SAN_FLAGS) -c $< -o $@

# --version and the metrics' build_info carry VERSION (-DIT2N_VERSION).
$(BUILD)/host/daemon/main.o $(BUILD)/san/daemon/main.o $(BUILD)/host/daemon/metrics.o \
  $(BUILD)/san/daemon/metrics.o: VERSION

$(BUILD)/host/daemon/%.o: daemon/%.c $(DAEMON_HDR)
	@mkdir -p $(@D)
	$(CC) $(DAEMON_CFLAGS) -c $< -o $@

$(BUILD)/san/daemon/%.o: daemon/%.c $(DAEMON_HDR)
	@mkdir -p $(@D)
	$(CC) $(DAEMON_CFLAGS) $(SAN_FLAGS) -c $< -o $@

$(IT2ND): $(DAEMON_OBJ) $(REGMAP_LIB) $(PROTO_LIB) $(CORE_LIB)
	$(CC) $(DAEMON_CFLAGS) $(DAEMON_OBJ) -o $@ $(REGMAP_LIB) $(PROTO_LIB) $(CORE_LIB) $(DAEMON_LIBS)

$(IT2ND_SAN): $(DAEMON_SAN_OBJ) $(REGMAP_SAN_LIB) $(PROTO_SAN_LIB) $(CORE_SAN_LIB)
	$(CC) $(DAEMON_CFLAGS) $(SAN_FLAGS) $(DAEMON_SAN_OBJ) -o $@ $(REGMAP_SAN_LIB) $(PROTO_SAN_LIB) $(CORE_SAN_LIB) $(DAEMON_LIBS)

# make run PORT=15020 STATE=./state2 METRICS=127.0.0.1:9102: the same as
# it2nd --listen 127.0.0.1:15020 --state-dir ./state2 --metrics ... (PORT
# may be HOST:PORT).
RUN_LISTEN = $(if $(PORT),$(if $(findstring :,$(PORT)),$(PORT),127.0.0.1:$(PORT)),127.0.0.1:1502)
RUN_PORT = $(lastword $(subst :, ,$(RUN_LISTEN)))
RUN_HOST = $(patsubst %:$(RUN_PORT),%,$(RUN_LISTEN))
RUN_FLAGS = $(if $(CONF),-c $(CONF)) $(if $(PORT),--listen $(RUN_LISTEN)) $(if $(STATE),--state-dir $(STATE)) $(if $(METRICS),--metrics $(METRICS))
run: deps all ## Start it2nd in the foreground (PORT=15020 STATE=./state2 METRICS=127.0.0.1:9102 CONF=it2nd.conf optional)
	@echo "$(if $(CONF),it2nd: configuration $(CONF),it2nd: Modbus TCP on $(RUN_LISTEN), model 1 on unit 1 (paper data), state in $(or $(STATE),./state))$(if $(METRICS), metrics on http://$(METRICS)/metrics)"
	@echo "query it from another shell, e.g. the status block and the D-footprint sample grid:"
	@echo "  mbpoll -m tcp -a 1 -0 -r 0 -c 10 -t 3 -1 $(RUN_HOST) -p $(RUN_PORT)"
	@echo "  mbpoll -m tcp -a 1 -0 -r 1024 -c 12 -t 4 -1 $(RUN_HOST) -p $(RUN_PORT)"
	exec $(IT2ND) --foreground -v $(RUN_FLAGS)

.PHONY: install-daemon
install-daemon: $(IT2ND)
	install -D -m 0755 $(IT2ND) $(DESTDIR)$(SBINDIR)/it2nd
	@# The units name the binary and the configuration by path: point them at
	@# SBINDIR and SYSCONFDIR. UNITDIR is where systemd looks (mk/install.mk).
	for u in it2nd.service it2nd@.service; do \
	  sed -e 's|/usr/local/sbin/it2nd|$(SBINDIR)/it2nd|' -e 's|/etc/it2n/|$(SYSCONFDIR)/it2n/|' \
	    daemon/$$u > $(BUILD)/$$u.tmp && \
	  install -D -m 0644 $(BUILD)/$$u.tmp $(DESTDIR)$(UNITDIR)/$$u && rm -f $(BUILD)/$$u.tmp; \
	done
	install -D -m 0644 daemon/it2nd.conf.example $(DESTDIR)$(SYSCONFDIR)/it2n/it2nd.conf.example
	@# it2nd.conf (read by the unit): the example with the unit's state
	@# directory; an existing one is the operator's and is kept.
	if [ -e $(DESTDIR)$(SYSCONFDIR)/it2n/it2nd.conf ]; then \
	  echo "install-daemon: keeping the existing $(DESTDIR)$(SYSCONFDIR)/it2n/it2nd.conf"; \
	else \
	  sed -e 's|^state_dir = \./state$$|state_dir = /var/lib/it2n|' \
	    -e '1a ; Installed from it2nd.conf.example with state_dir = /var/lib/it2n (the unit'"'"'s StateDirectory).' \
	    daemon/it2nd.conf.example \
	    > $(BUILD)/it2nd.conf.tmp && \
	  install -D -m 0644 $(BUILD)/it2nd.conf.tmp $(DESTDIR)$(SYSCONFDIR)/it2n/it2nd.conf && \
	  rm -f $(BUILD)/it2nd.conf.tmp; \
	fi
	install -D -m 0644 daemon/it2nd.8 $(DESTDIR)$(MANDIR)/man8/it2nd.8
