# make format / make format-check: the code layout of .clang-format (the
# core's style) over the product code, with clang-format 14 (Debian's
# clang-format package, in DEB_PACKAGES). The lint suite runs the check
# (mk/lint.mk) and tests/lint/format_test.sh, which shows it can fail.
CLANG_FORMAT ?= clang-format
export CLANG_FORMAT

# The files held to it, one list for every use: each C source and header
# under the product directories (found, so a new file is covered without
# being listed; tests/ is not product code), less the generated ones
# (their generators write them; firmware_core/it2n_uniform_inv.c:
# `make core-tables`; protocol/it2n_vectors.inc is no .c/.h).
FORMAT_DIRS := firmware_core protocol regmap daemon cli examples
FORMAT_GENERATED := firmware_core/it2n_uniform_inv.c
FORMAT_FILES := $(filter-out $(FORMAT_GENERATED),$(sort $(shell find $(FORMAT_DIRS) -name '*.[ch]' 2>/dev/null)))

.PHONY: format format-check
format: ## Rewrite the product code's layout as .clang-format says (clang-format 14)
	mk/format.sh fix $(FORMAT_FILES)

format-check: ## Fail naming each product file clang-format would change (and how); `make format` fixes
	@mk/format.sh check $(FORMAT_FILES)
