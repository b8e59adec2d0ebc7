# tests/install/: what `make install` and the Debian package deliver.
#   test-install     make install into a scratch DESTDIR with PREFIX=/opt/it2n:
#                    the full layout, units where systemd looks, it2nd.conf
#                    kept on reinstall, a pkg-config consumer, completions
#   test-completion  the bash completions (completions/) and the man pages
#                    agree with each program's --help
#   deb-check        (not in make test: about a minute) builds the .debs with
#                    `make deb`, checks them with dpkg-deb and lintian
#   deb-smoke        (in make test) debian/ agrees with make install and cli.h
# docs/packaging.md describes the layout and the package.
DEB_PACKAGES += bash-completion

# Every program that has a completion file, with its binary and man page.
COMPLETION_PROGS := it2n=$(CLI_BIN):cli/it2n.1 it2nd=$(IT2ND):daemon/it2nd.8 \
  it2n-instrument=$(BUILD)/host/it2n-instrument:examples/instrument/it2n-instrument.1

.PHONY: test-install test-completion
test-install: $(CLI_BIN) $(IT2ND) $(BUILD)/host/it2n-instrument $(CORE_LIB) $(PROTO_LIB)
	@MAKE="$(MAKE)" CC="$(CC)" tests/install/test_install.sh

test-completion: $(CLI_BIN) $(IT2ND) $(BUILD)/host/it2n-instrument ## Check the bash completions and man pages against each program's --help
	@/usr/bin/python3 tests/install/test_completion.py completions $(COMPLETION_PROGS)

TEST_TARGETS += test-install test-completion
