# tests/cli/ctl.mk: it2nctl against a real it2nd (TCP, a pty link, RTU on a
# pty pair), every answer compared with it2n on the same file; normal and
# sanitized builds. Ports from 23000..23999. (The pty bridge is named by
# path: tests/daemon/ defines SIM_PTY after this fragment is read.)
.PHONY: ctl-test
TEST_TARGETS += ctl-test

ctl-test: $(CTL_BIN) $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(BUILD)/tests/sim/ptybridge ## it2nctl end to end against it2nd (TCP, link, RTU)
	timeout 300 /usr/bin/python3 tests/cli/ctl_e2e.py $(CTL_BIN) $(CLI_BIN) $(IT2ND) $(BUILD)/tests/sim/ptybridge
	timeout 300 /usr/bin/python3 tests/cli/ctl_e2e.py $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(BUILD)/tests/sim/ptybridge
