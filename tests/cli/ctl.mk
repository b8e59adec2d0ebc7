# tests/cli/ctl.mk: it2nctl against a real it2nd (TCP, a pty link, RTU on a
# pty pair), every answer compared with it2n on the same file; normal and
# sanitized builds. Ports from 23000..23999. (The pty bridge is named by
# path: tests/daemon/ defines SIM_PTY after this fragment is read.)
.PHONY: ctl-e2e
TEST_TARGETS += ctl-e2e

ctl-e2e: $(CTL_BIN) $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(BUILD)/tests/sim/ptybridge ## it2nctl end to end against it2nd (TCP, link, RTU)
	timeout 300 /usr/bin/python3 tests/cli/ctl_e2e.py $(CTL_BIN) $(CLI_BIN) $(IT2ND) $(BUILD)/tests/sim/ptybridge
	timeout 300 /usr/bin/python3 tests/cli/ctl_e2e.py $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(BUILD)/tests/sim/ptybridge

# The B-spline kind end to end (issue 21): a 64x64 survey pushed with
# it2nctl, read back by a PLC (pymodbus) bit for bit against it2n, plotted,
# kept across kill -9 and a restart; then again with it2nd and it2nctl
# under ASan+UBSan. Ports 24000..24999.
.PHONY: ctl-bspline
TEST_TARGETS += ctl-bspline

ctl-bspline: $(CTL_BIN) $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND) $(IT2ND_SAN) ## B-spline survey: it2nctl push -> it2nd -> PLC (pymodbus), bit for bit; plot; kill -9
	timeout 180 /usr/bin/python3 tests/cli/ctl_bspline_e2e.py $(CTL_BIN) $(CLI_BIN) $(IT2ND)
	ASAN_OPTIONS=verify_asan_link_order=0 timeout 180 /usr/bin/python3 tests/cli/ctl_bspline_e2e.py \
	  $(CTL_SAN_BIN) $(CLI_BIN) $(IT2ND_SAN)
