# mk/install.mk: where `make install` puts things (GNU-style names, each
# overridable on the command line) and the install rules that belong to no
# single directory: the libraries, headers and pkg-config files, the example
# instrument, the examples and the bash completions. daemon/daemon.mk
# installs it2nd, its units and it2nd.conf with these directories; cli/cli.mk
# installs the CLI's programs and man pages under PREFIX/bin, PREFIX/share/man
# (what BINDIR and MANDIR default to). The Debian package (debian/rules, `make deb`) is
# `make install DESTDIR=debian/tmp PREFIX=/usr LIBDIR=/usr/lib/<triplet>`.
# Layout and the reasons: docs/packaging.md.
BINDIR      ?= $(PREFIX)/bin
SBINDIR     ?= $(PREFIX)/sbin
LIBDIR      ?= $(PREFIX)/lib
INCLUDEDIR  ?= $(PREFIX)/include
DATADIR     ?= $(PREFIX)/share
MANDIR      ?= $(DATADIR)/man
DOCDIR      ?= $(DATADIR)/doc/it2n
EXAMPLESDIR ?= $(DOCDIR)/examples
PKGCONFIGDIR ?= $(LIBDIR)/pkgconfig
# bash-completion finds it through XDG_DATA_DIRS (/usr/local/share:/usr/share
# by default; bash-completion >= 2.12 also looks next to the program).
BASHCOMPDIR ?= $(DATADIR)/bash-completion/completions
# Not under PREFIX: the configuration stays in /etc, and the units go where
# systemd looks for them (/opt/it2n/lib/systemd/system would never be
# found); the paths inside the units are rewritten to PREFIX and SYSCONFDIR.
SYSCONFDIR  ?= /etc
ifeq ($(origin UNITDIR),undefined)
UNITDIR := $(or $(shell pkg-config --variable=systemdsystemunitdir systemd 2>/dev/null),/lib/systemd/system)
endif

# What the libraries' users include: as CMakeLists.txt installs it.
INSTALL_HEADERS := firmware_core/it2n.h $(wildcard protocol/*.h) $(REGMAP_HDR)
# pkg-config files from CMake's templates (cmake/*.pc.in) with this PREFIX.
INSTALL_PC := $(BUILD)/pkgconfig/it2n.pc $(BUILD)/pkgconfig/it2n-protocol.pc $(BUILD)/pkgconfig/it2n-regmap.pc
IT2N_INSTRUMENT := $(BUILD)/host/it2n-instrument

INSTALL_TARGETS += install-lib install-instrument install-examples install-completion

# ${prefix}/lib rather than /usr/lib where the directory is under PREFIX.
pc_rel = $(patsubst $(PREFIX)/%,$${prefix}/%,$(1))
$(BUILD)/pkgconfig/%.pc: cmake/%.pc.in VERSION FORCE_PC
	@mkdir -p $(@D)
	@sed -e 's|@IT2N_PC_PREFIX@|$(PREFIX)|' -e 's|@IT2N_PC_LIBDIR@|$(call pc_rel,$(LIBDIR))|' \
	  -e 's|@IT2N_PC_INCLUDEDIR@|$(call pc_rel,$(INCLUDEDIR))|' -e 's|@IT2N_PC_CFLAGS@||' \
	  -e 's|@IT2N_PROTO_PC_CFLAGS@| $(PROTO_HOST_DEFS)|' \
	  -e 's|@PROJECT_VERSION@|$(IT2N_VERSION)|' $< > $@.tmp && mv $@.tmp $@
# Rebuilt every time: the paths depend on the command line, not on files.
.PHONY: FORCE_PC
FORCE_PC:

.PHONY: install-lib install-instrument install-examples install-completion
install-lib: $(CORE_LIB) $(PROTO_LIB) $(REGMAP_LIB) $(INSTALL_PC)
	install -d $(DESTDIR)$(LIBDIR) $(DESTDIR)$(INCLUDEDIR)/it2n $(DESTDIR)$(PKGCONFIGDIR)
	install -m 0644 $(CORE_LIB) $(PROTO_LIB) $(REGMAP_LIB) $(DESTDIR)$(LIBDIR)/
	install -m 0644 $(INSTALL_HEADERS) $(DESTDIR)$(INCLUDEDIR)/it2n/
	install -m 0644 $(INSTALL_PC) $(DESTDIR)$(PKGCONFIGDIR)/

install-instrument: $(IT2N_INSTRUMENT)
	install -D -m 0755 $(IT2N_INSTRUMENT) $(DESTDIR)$(BINDIR)/it2n-instrument
	install -D -m 0644 examples/instrument/it2n-instrument.1 $(DESTDIR)$(MANDIR)/man1/it2n-instrument.1

# The data sets the man pages and docs use, and the firmware/instrument
# sources (they build against libit2n-dev).
INSTALL_EXAMPLES := $(wildcard examples/*.csv) $(wildcard examples/firmware/*.[ch]) \
  $(wildcard examples/instrument/*.[ch]) examples/instrument/README.md
install-examples:
	@set -e; for f in $(INSTALL_EXAMPLES); do \
	  echo "install -D -m 0644 $$f $(DESTDIR)$(EXAMPLESDIR)/$${f#examples/}"; \
	  install -D -m 0644 $$f $(DESTDIR)$(EXAMPLESDIR)/$${f#examples/}; done

# One file per program, named after it (bash-completion loads it on demand).
INSTALL_COMPLETIONS := completions/it2n completions/it2nd completions/it2n-instrument \
  completions/it2nctl
install-completion:
	install -d $(DESTDIR)$(BASHCOMPDIR)
	install -m 0644 $(INSTALL_COMPLETIONS) $(DESTDIR)$(BASHCOMPDIR)/

# ---- Debian package -----------------------------------------------------------
# `make deb` builds it2n_VERSION_ARCH.deb and libit2n-dev_VERSION_ARCH.deb
# with debhelper (debian/) from a copy of the tree, into $(DEB_OUT).
# Its own Debian packages are installed by `make deb` (deb-deps), so only
# `make deb` and deb-check (in make test) pull in debhelper and lintian.
DEB_OUT ?= $(BUILD)/deb
DEB_TOOL_PACKAGES := debhelper dpkg-dev fakeroot lintian pkg-config libinih-dev \
  libmodbus-dev liburing-dev libusb-1.0-0-dev systemd
.PHONY: deb deb-deps
deb-deps:
	@$(MAKE) --no-print-directory deps DEB_PACKAGES="$(DEB_TOOL_PACKAGES)"

deb: deb-deps ## Build the Debian packages it2n and libit2n-dev into build/deb/ (docs/packaging.md)
	@mk/deb.sh $(DEB_OUT) && touch $(DEB_STAMP)

# The packages as of the sources mk/deb.sh copies (tracked and untracked, not
# ignored): what the deb suites check. make test's first step builds them
# once; the suites (tests/install/install.mk) do not build them again unless
# a source is newer than the stamp. (Checked in the recipe, not by listing the
# sources as prerequisites: make would then remake a generated one, such as
# docs/registers.md, before regmap-doc could find it stale.)
DEB_STAMP := $(DEB_OUT)/built.stamp
.PHONY: deb-if-changed
deb-if-changed:
$(DEB_STAMP): deb-if-changed | deb-deps
	@if git rev-parse --is-inside-work-tree >/dev/null 2>&1 && [ -f $@ ] && \
	    [ -z "$$(git ls-files -z --cached --others --exclude-standard | \
	             xargs -0 -r sh -c 'for f; do [ ! "$$f" -nt "$$0" ] || echo "$$f"; done' $@ | head -n 1)" ]; then \
	  echo "deb: $(DEB_OUT) is current (no source newer than $@)"; \
	else mk/deb.sh $(DEB_OUT) && touch $@; fi
deb-check deb-contents deb-lintian: $(DEB_STAMP)
# The package build is one long chain of steps (dpkg-buildpackage): make
# test's first step starts it before the rest (tests/run_suites.py).
TEST_BUILD_FIRST += $(DEB_STAMP)
