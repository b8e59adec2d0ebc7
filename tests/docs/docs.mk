# tests/docs/: figures in README.md and docs/ that come from the build
# (docfig.py: `<!-- fig:NAME -->` blocks). docs-figures rewrites them;
# docs-check (make test) fails if a committed figure differs from the build.
# (The cross builds and what `make size` reads are added in mk/cross.mk, read
# after this file.)
DOCFIG_DEPS = $(BUILD)/tests/core/test_accuracy $(BUILD)/tests/core/test_operations \
              $(BUILD)/tests/core/test_bspline $(BUILD)/tests/daemon/test_models $(IT2ND)

.PHONY: docs-figures docs-check
docs-figures: $(DOCFIG_DEPS) ## Regenerate the build figures quoted in README.md and docs/
	@BUILD=$(BUILD) /usr/bin/python3 tests/docs/docfig.py --write

docs-check: $(DOCFIG_DEPS)
	@BUILD=$(BUILD) /usr/bin/python3 tests/docs/docfig.py --check
	@/usr/bin/python3 tests/docs/design_check.py .
	@# self-test: docs/daemon.md's key reference (generated from
	@# daemon/conf_schema.c) with one range edited by hand must fail
	@mkdir -p $(BUILD)
	@sed 's/^| `max_clients` | 1\.\.512 |/| `max_clients` | 1..511 |/' docs/daemon.md > $(BUILD)/daemon_drift.md
	@if cmp -s docs/daemon.md $(BUILD)/daemon_drift.md; then \
	  echo "docs-check: self-test found no max_clients row to edit"; exit 1; fi
	@if BUILD=$(BUILD) /usr/bin/python3 tests/docs/docfig.py --check $(BUILD)/daemon_drift.md \
	    > $(BUILD)/daemon_drift.log 2>&1; then \
	  echo "docs-check: a key table edited by hand passed"; exit 1; \
	else echo "docs-check: a key table that differs from the schema is refused (self-test)"; fi

TEST_TARGETS += docs-check

# Every sh/c/python block of README.md and docs/*.md run or compiled as
# written, and every `make TARGET` the docs name listed by `make help`
# (snippets.py: the marking rule; README "Documentation checks").
.PHONY: docs-snippets
docs-snippets: all
	@BUILD=$(BUILD) /usr/bin/python3 tests/docs/snippets.py
	@# self-test: a session page whose blocks hold only in another order fails
	@if BUILD=$(BUILD) /usr/bin/python3 tests/docs/snippets.py tests/docs/fixtures/session_order.md \
	    > $(BUILD)/session_order.log 2>&1; then \
	  echo "docs-snippets: session_order.md passed: sessions do not carry state"; exit 1; \
	elif ! grep -q "stdout differs" $(BUILD)/session_order.log; then \
	  cat $(BUILD)/session_order.log; exit 1; \
	else echo "docs snippets: a session run out of order is refused (self-test)"; fi

TEST_TARGETS += docs-snippets

# docs/protocol.md section 9: every rule names tests that exist and run in
# make test, every question of section 4.4 has a row (conformance.py); the
# self-test renames one test and must see the check fail.
.PHONY: docs-conformance
docs-conformance: ## Check the protocol conformance table against the test sources
	@/usr/bin/python3 tests/docs/conformance.py
	@mkdir -p $(BUILD)
	@sed 's/test_seq_wraps/test_seq_wraps_renamed/' docs/protocol.md > $(BUILD)/conformance_drift.md
	@if /usr/bin/python3 tests/docs/conformance.py $(BUILD)/conformance_drift.md > $(BUILD)/conformance_drift.log 2>&1; then \
	  echo "docs-conformance: a table naming a missing test passed"; exit 1; \
	else echo "docs-conformance: a table naming a missing test is refused (self-test)"; fi

TEST_TARGETS += docs-conformance
