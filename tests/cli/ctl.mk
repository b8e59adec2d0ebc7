# tests/cli/ctl.mk: it2nctl against a real it2nd (TCP, a pty link, RTU on a
# pty pair), every answer compared with it2n on the same file; normal and
# sanitized builds. Ports from 23000..23999.
.PHONY: ctl-test
TEST_TARGETS += ctl-test

ctl-test: $(CTL_BIN) $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(SIM_PTY) ## it2nctl end to end against it2nd (TCP, link, RTU)
	timeout 300 /usr/bin/python3 tests/cli/ctl_e2e.py $(CTL_BIN) $(CLI_BIN) $(IT2ND) $(SIM_PTY)
	timeout 300 /usr/bin/python3 tests/cli/ctl_e2e.py $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(SIM_PTY)
