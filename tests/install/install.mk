# make install into a scratch DESTDIR with a non-default PREFIX: every file
# lands where the docs say, and the units point at the installed binary.
.PHONY: test-install
test-install:
	@d=$$(mktemp -d); trap 'rm -rf $$d' EXIT; \
	$(MAKE) --no-print-directory -s install DESTDIR=$$d PREFIX=/opt/it2n >/dev/null && \
	for f in opt/it2n/bin/it2n opt/it2n/sbin/it2nd opt/it2n/share/man/man1/it2n.1 \
	         opt/it2n/share/man/man8/it2nd.8 etc/it2n/it2nd.conf.example \
	         opt/it2n/lib/systemd/system/it2nd.service opt/it2n/lib/systemd/system/it2nd@.service; do \
	  test -s $$d/$$f || { echo "test-install: missing $$f" >&2; exit 1; }; \
	done && \
	grep -q '^ExecStart=/opt/it2n/sbin/it2nd ' $$d/opt/it2n/lib/systemd/system/it2nd.service && \
	grep -q '^ExecStart=/opt/it2n/sbin/it2nd ' $$d/opt/it2n/lib/systemd/system/it2nd@.service || \
	  { echo "test-install: units do not point at PREFIX/sbin/it2nd" >&2; exit 1; }; \
	$$d/opt/it2n/bin/it2n --version >/dev/null && $$d/opt/it2n/sbin/it2nd --version >/dev/null && \
	echo "test-install: ok (PREFIX=/opt/it2n, DESTDIR=scratch)"

TEST_TARGETS += test-install
