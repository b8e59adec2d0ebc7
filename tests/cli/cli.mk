# tests/cli: text conversion and CSV reader unit tests (cmocka), the CSV
# fuzzer's fixed corpus, and end-to-end runs of the it2n binary against an
# exact rational reference. Everything is built normally and with $(SAN_FLAGS).
CLI_T := $(BUILD)/tests/cli
CLI_T_LIBS := -lcmocka
FUZZ_SECONDS ?= 60

$(CLI_T)/%: tests/cli/%.c $(CLI_CSV_OBJ) $(CORE_LIB) $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -Icli/common -o $@ $< $(CLI_CSV_OBJ) $(CORE_LIB) $(CLI_T_LIBS)

$(CLI_T)/san/%: tests/cli/%.c $(CLI_CSV_SAN_OBJ) $(CORE_SAN_LIB) $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -Icli/common -o $@ $< $(CLI_CSV_SAN_OBJ) \
	  $(CORE_SAN_LIB) $(CLI_T_LIBS)

# The front ends' shared code (option parser, output layer) with its tests.
CLI_T_FRONT := test_opt test_out
$(addprefix $(CLI_T)/,$(CLI_T_FRONT)): $(CLI_T)/%: tests/cli/%.c $(CLI_COMMON_OBJ) $(CORE_LIB) $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -Icli/common -o $@ $< $(CLI_COMMON_OBJ) $(CORE_LIB) $(CLI_T_LIBS)

$(addprefix $(CLI_T)/san/,$(CLI_T_FRONT)): $(CLI_T)/san/%: tests/cli/%.c $(CLI_COMMON_SAN_OBJ) $(CORE_SAN_LIB) $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) -Icli/common -o $@ $< \
	  $(CLI_COMMON_SAN_OBJ) $(CORE_SAN_LIB) $(CLI_T_LIBS)

CLI_T_UNITS := test_text test_csv $(CLI_T_FRONT)
CLI_T_BINS := $(addprefix $(CLI_T)/,$(CLI_T_UNITS)) \
              $(addprefix $(CLI_T)/san/,$(CLI_T_UNITS) fuzz_csv)

.PHONY: cli-unit cli-corpus cli-e2e cli-fuzz cli-plot cli-docs
TEST_TARGETS += cli-unit cli-corpus cli-e2e cli-plot cli-docs
FUZZ_TARGETS += cli-fuzz

cli-unit: $(CLI_T_BINS)
	@for t in $(CLI_T_UNITS); do \
	  $(CLI_T)/$$t && $(CLI_T)/san/$$t || exit 1; \
	done

cli-corpus: $(CLI_T)/san/fuzz_csv
	$(CLI_T)/san/fuzz_csv tests/cli/corpus

cli-e2e: $(CLI_BIN) $(CLI_SAN_BIN)
	python3 tests/cli/e2e.py $(CLI_BIN)
	python3 tests/cli/e2e.py $(CLI_SAN_BIN)
	python3 tests/cli/e2e_bspline.py $(CLI_BIN)
	python3 tests/cli/e2e_bspline.py $(CLI_SAN_BIN)

# examples/survey_64x64.csv is generated (exact arithmetic) and checked in.
.PHONY: examples-survey examples-check
examples-survey: ## Regenerate examples/survey_64x64.csv
	/usr/bin/python3 examples/gen_survey.py > examples/survey_64x64.csv

examples-check:
	@/usr/bin/python3 examples/gen_survey.py | cmp -s - examples/survey_64x64.csv || \
	  { echo "examples/survey_64x64.csv differs from examples/gen_survey.py: run 'make examples-survey'" >&2; exit 1; }
	@echo "examples-check: examples/survey_64x64.csv matches its generator"

TEST_TARGETS += examples-check

# plot (gnuplot PNG/SVG checked as images), export (meshes parsed back and
# compared with sample), sample --footprint; also the committed figures.
cli-plot: $(CLI_BIN) $(CLI_SAN_BIN)
	/usr/bin/python3 tests/cli/plot_export.py $(CLI_BIN) \
	  $(addprefix --figure ,$(CLI_FIGURES))
	/usr/bin/python3 tests/cli/plot_export.py $(CLI_SAN_BIN)

# The it2n command blocks marked `<!-- run: it2n -->` in README.md and
# docs/cli.md and the EXAMPLES of it2n(1), run as written with build/host
# first on PATH.
cli-docs: $(CLI_BIN)
	/usr/bin/python3 tests/cli/doc_cmds.py $(CLI_BIN) README.md docs/cli.md cli/it2n/it2n.1

# ... and no function of the front ends over 100 lines (tests/cli/fn_length.py;
# --allow FILE:NAME would let one through for now: none is).
CLI_FN_ALLOW :=
# make lint runs it (mk/lint.mk).
LINT_CLI_FN = /usr/bin/python3 tests/cli/fn_length.py --max 100 $(CLI_FN_ALLOW) $(sort $(wildcard cli/*/*.c))

# libFuzzer build: clang instruments the core and the reader too.
CLI_FUZZ_BIN := $(BUILD)/fuzz/cli_fuzz_csv
$(CLI_FUZZ_BIN): tests/cli/fuzz_csv.c cli/common/csv.c $(CORE_SRC) $(CLI_HDR) $(CORE_HDR)
	@mkdir -p $(@D)
	clang -std=c11 -D_GNU_SOURCE -DFUZZ_LIBFUZZER -O1 -g \
	  -fsanitize=fuzzer,address,undefined -Ifirmware_core -Icli/common \
	  -o $@ tests/cli/fuzz_csv.c cli/common/csv.c $(CORE_SRC)

cli-fuzz: $(CLI_FUZZ_BIN)
	@rm -rf $(BUILD)/fuzz/cli_corpus; mkdir -p $(BUILD)/fuzz/cli_corpus
	$(CLI_FUZZ_BIN) -max_total_time=$(FUZZ_SECONDS) -max_len=4096 \
	  -timeout=10 $(BUILD)/fuzz/cli_corpus tests/cli/corpus
