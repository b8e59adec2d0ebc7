# tests/docs/: figures in README.md and docs/ that come from the build
# (docfig.py: `<!-- fig:NAME -->` blocks). docs-figures rewrites them;
# docs-check (make test) fails if a committed figure differs from the build.
DOCFIG_DEPS = cross $(BUILD)/tests/core/test_accuracy $(BUILD)/tests/core/test_operations \
              $(BUILD)/tests/core/test_bspline $(BUILD)/tests/daemon/test_models

.PHONY: docs-figures docs-check
docs-figures: $(DOCFIG_DEPS) ## Regenerate the build figures quoted in README.md and docs/
	@BUILD=$(BUILD) /usr/bin/python3 tests/docs/docfig.py --write

docs-check: $(DOCFIG_DEPS)
	@BUILD=$(BUILD) /usr/bin/python3 tests/docs/docfig.py --check
	@/usr/bin/python3 tests/docs/design_check.py .

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
