# tests/install/: what `make install` and the Debian package deliver.
#   pkg-install      make install into a scratch DESTDIR with PREFIX=/opt/it2n:
#                    the full layout, units where systemd looks, it2nd.conf
#                    kept on reinstall, a pkg-config consumer, completions
#   pkg-completion   the bash completions (completions/) and the man pages
#                    agree with each program's --help
#   deb-check        (in make test, about 30 s to 2 min) builds the .debs
#                    with `make deb`, checks them with dpkg-deb and lintian
#   deb-smoke        (in make test) debian/ agrees with make install and VERSION
#   pkg-version      VERSION = library.json = debian/changelog = --version of
#                    it2n, it2nctl, it2nd = the .pc files of make and CMake
#   pkg-cflags       make CFLAGS=/CPPFLAGS=/LDFLAGS= reach every host compile
#                    and link, after the required flags
# docs/packaging.md describes the layout and the package.
# bash-completion (pkg-completion), dpkg-dev (dpkg-parsechangelog,
# dpkg-architecture: deb-smoke), man-db (man page warnings: pkg-install).
DEB_PACKAGES += bash-completion dpkg-dev man-db

# Every program that has a completion file, with its binary and man page
COMPLETION_PROGS := it2n=$(CLI_BIN):cli/it2n/it2n.1 it2nd=$(IT2ND):daemon/it2nd.8 \
  it2n-instrument=$(BUILD)/host/it2n-instrument:examples/instrument/it2n-instrument.1 \
  it2nctl=$(CTL_BIN):cli/it2nctl/it2nctl.1

.PHONY: pkg-install pkg-completion
pkg-install: $(CLI_BIN) $(IT2ND) $(BUILD)/host/it2n-instrument $(CORE_LIB) $(PROTO_LIB) $(REGMAP_LIB)
	@MAKE="$(MAKE)" CC="$(CC)" tests/install/test_install.sh

pkg-completion: $(CLI_BIN) $(IT2ND) $(BUILD)/host/it2n-instrument $(CTL_BIN) ## Check the bash completions and man pages against each program's --help
	@/usr/bin/python3 tests/install/test_completion.py completions $(COMPLETION_PROGS)

TEST_TARGETS += pkg-install pkg-completion

# make CFLAGS=... CPPFLAGS=... LDFLAGS=... reaches every host compile and
# link (Makefile, USER_FLAGS): make -n of the programs, the libraries and
# the test programs of each area (tests/install/cflags_check.sh).
PKG_CFLAGS_TARGETS = all $(CORE_SAN_LIB) $(TC_BIN) $(TC_CONFIG_BIN) $(PROTO_TEST_BINS) \
  $(DT_UNIT_BINS) $(FZD_BINS) $(CLI_SAN_BIN) $(CTL_SAN_BIN) $(IT2ND_SAN) $(SIM_PLC) $(SIM_INSTR) \
  $(VEC_B)/host_check $(RM_TB)/test_regmap
.PHONY: pkg-cflags
pkg-cflags:
	@MAKE="$(MAKE)" tests/install/cflags_check.sh "$(CC)" $(PKG_CFLAGS_TARGETS)

TEST_TARGETS += pkg-cflags

# VERSION is the version of every program, library, package and manifest
# (tests/install/version_check.py); the self-test compares against 9.9.9
# and must see every place disagree.
.PHONY: pkg-version
pkg-version: $(CLI_BIN) $(CTL_BIN) $(IT2ND) $(addprefix $(BUILD)/pkgconfig/,it2n.pc it2n-protocol.pc it2n-regmap.pc)
	@/usr/bin/python3 tests/install/version_check.py --build $(BUILD) $(CLI_BIN) $(CTL_BIN) $(IT2ND)
	@mkdir -p $(BUILD); echo 9.9.9 > $(BUILD)/version_drift
	@if /usr/bin/python3 tests/install/version_check.py --version-file $(BUILD)/version_drift --build $(BUILD) \
	    $(CLI_BIN) $(CTL_BIN) $(IT2ND) > $(BUILD)/version_drift.log 2>&1; then \
	  echo "pkg-version: a VERSION no other place says passed"; exit 1; \
	else echo "pkg-version: a VERSION the others disagree with is refused (self-test: $$(grep -c FAIL $(BUILD)/version_drift.log) mismatches)"; fi

TEST_TARGETS += pkg-version

.PHONY: deb-smoke deb-check deb-contents deb-lintian
deb-smoke: $(CLI_BIN) $(IT2ND) $(BUILD)/host/it2n-instrument $(CORE_LIB) $(PROTO_LIB) $(REGMAP_LIB)
	@d=$$(mktemp -d); trap 'rm -rf $$d' EXIT; \
	u=$$(pkg-config --variable=systemdsystemunitdir systemd 2>/dev/null); u=$${u:-/lib/systemd/system}; \
	$(MAKE) --no-print-directory -s install DESTDIR=$$d PREFIX=/usr \
	  LIBDIR=/usr/lib/$$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch) \
	  UNITDIR=$$u >$$d.log 2>&1 || { cat $$d.log >&2; rm -f $$d.log; exit 1; }; rm -f $$d.log; \
	/usr/bin/python3 tests/install/deb_smoke.py $$d $$u

deb-check: ## Build the Debian packages and check them (dpkg-deb -I/-c, unpacked programs, lintian; docs/packaging.md)
	@MAKE="$(MAKE)" CC="$(CC)" tests/install/deb_check.sh $(DEB_OUT)

# make test runs deb-check as two suites: deb-contents runs make install (so
# it runs alone, tests/run_suites.py), deb-lintian (most of the time) runs
# no make and shares the machine. (Their prerequisite, the packages built
# once from the sources, is named in mk/install.mk, read after this file.)
deb-contents:
	@MAKE="$(MAKE)" CC="$(CC)" tests/install/deb_check.sh $(DEB_OUT) contents
deb-lintian:
	@tests/install/deb_check.sh $(DEB_OUT) lintian

TEST_TARGETS += deb-smoke deb-contents deb-lintian
