# tests/lib: the helpers shared by the Python and shell test scripts
# (it2ntest/, testlib.sh) and their self-test (a failing check fails the
# script, skips are said as skips, ports, Daemon, testlib.sh), ~3 s.
TEST_TARGETS += lib-unit
.PHONY: lib-unit
lib-unit: ## Self-test of the shared test helpers tests/lib (it2ntest, testlib.sh)
	timeout 120 /usr/bin/python3 tests/lib/test_lib.py
