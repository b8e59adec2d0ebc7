# tests/bench/: core benchmark. `make bench` prints ratios measured in one
# run (update vs re-solve, sample vs eval, solve by degree) and, when
# valgrind is installed, callgrind instruction counts per operation.
# `bench-smoke` (in make test) runs ~1 s and checks results, never times.
BENCH_B := $(BUILD)/bench

$(BENCH_B)/bench_core: tests/bench/bench_core.c $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $< $(CORE_LIB) -o $@

.PHONY: bench-core bench-callgrind bench-smoke
bench-core: $(BENCH_B)/bench_core
	$<

# Inclusive instruction counts of each public operation, one call each at
# degree 7x7 (sample: 16x16 nodes; eval: 256 calls).
bench-callgrind: $(BENCH_B)/bench_core
	@if ! command -v valgrind >/dev/null; then echo "bench-callgrind: valgrind not installed, skipped"; exit 0; fi; \
	out=$(BENCH_B)/callgrind.out; \
	valgrind --tool=callgrind --callgrind-out-file=$$out $< --ops >/dev/null 2>&1 || exit 1; \
	echo "callgrind: instructions (inclusive), degree 7x7:"; \
	callgrind_annotate --inclusive=yes $$out 2>/dev/null | \
	  awk '$$0 ~ /=> .*:it2n_(model_solve|model_update|sample|eval) \(/ { \
	      ir = $$1; gsub(",", "", ir); f = $$0; sub(/.*:/, "", f); sub(/ .*/, "", f); \
	      n = $$NF; gsub(/[()x]/, "", n); c[f] = ir; k[f] = n } \
	    END { if (!("it2n_model_solve" in c)) { print "bench-callgrind: no counts" > "/dev/stderr"; exit 1 } \
	      for (f in c) printf "  %-18s %6d call(s) %14d Ir\n", f, k[f], c[f]; \
	      printf "  solve / update      %.1fx\n", c["it2n_model_solve"] / c["it2n_model_update"]; \
	      printf "  256 evals / sample  %.2fx\n", c["it2n_eval"] / c["it2n_sample"] }'

BENCH_TARGETS += bench-core bench-callgrind

# B-spline kind (issue 21): solve and query times by grid, and callgrind's
# instruction count of it2n_bspline_eval at 4x4 and 256x256 points (a query
# reads a 4x4 window: the goal is within 10 %), as rows of
# bench/bspline_host.json (the 256x256 solve's goal: 50 ms of CPU time, from
# interleaved rounds until its 95 % interval is within +-5 %, at most
# BSPLINE_ROUNDS: about 50 ms of CPU per round).
BSPLINE_ROUNDS ?= 40
$(BENCH_B)/bench_bspline: tests/bench/bench_bspline.c $(CORE_LIB)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $< $(CORE_LIB) -o $@

.PHONY: bench-bspline
bench-bspline: $(BENCH_B)/bench_bspline ## B-spline kind: solve/query times by grid, query instruction count 4x4 vs 256x256 -> bench/bspline_host.json
	@$< --time
	@if ! command -v valgrind >/dev/null; then echo "bench-bspline: valgrind not installed" >&2; exit 1; fi
	@/usr/bin/python3 tests/bench/mcu/bspline_rounds.py $< $(BSPLINE_ROUNDS) > $(BENCH_B)/bspline_host.log
	@for p in 4 256; do \
	  valgrind --tool=callgrind --callgrind-out-file=$(BENCH_B)/cg_bs_$$p.out $< --eval $$p >/dev/null 2>&1 || exit 1; \
	  callgrind_annotate --inclusive=yes $(BENCH_B)/cg_bs_$$p.out 2>/dev/null | \
	    awk -v p=$$p '$$0 ~ /=> .*:it2n_bspline_eval \(/ { ir = $$1; gsub(",", "", ir); print "R host.cg.eval" p, ir }'; \
	done >> $(BENCH_B)/bspline_host.log
	@mkdir -p bench
	@/usr/bin/python3 tests/bench/mcu/bspline_results.py host --log $(BENCH_B)/bspline_host.log --out bench/bspline_host.json
	@$(MAKE) --no-print-directory bench-collect

BENCH_TARGETS += bench-bspline

bench-smoke: $(BENCH_B)/bench_core
	$< --smoke

TEST_TARGETS += bench-smoke
include tests/bench/mcu/mcu.mk

# Every benchmark writes bench/<name>.json; bench-collect merges their rows
# into bench/results.json and renders docs/performance.md (run last by
# `make bench`). bench-results-check (make test) fails if the committed
# results.json or performance.md is not what the committed bench/*.json give,
# and feeds the collector rows whose rounding once failed (test_rows.py).
.PHONY: bench-collect bench-results-check
bench-collect: ## Merge bench/*.json rows into bench/results.json and docs/performance.md
	@/usr/bin/python3 tests/bench/collect.py bench
	@/usr/bin/python3 tests/bench/mcu/perfdoc.py bench/results.json docs/performance.md

bench-results-check:
	@/usr/bin/python3 tests/bench/test_rows.py
	@/usr/bin/python3 tests/bench/collect.py --check bench
	@/usr/bin/python3 tests/bench/mcu/perfdoc.py --check bench/results.json docs/performance.md

TEST_TARGETS += bench-results-check
include tests/bench/proto/proto.mk

# B-spline kind on emulated Cortex-M0+ (-Os) and Cortex-M4F (-O2):
# instruction counts of solve and query against a plain float baseline
# (tests/bench/mcu/bspline_image.c; issue 21's speed goals, measured).
BSMCU_OBJ = $(BMCU_B)/$(1)/bench/bspline_image.o $(BMCU_B)/$(1)/bench/entry.o \
            $(BMCU_B)/$(1)/bench/baseline_float.o \
            $(BMCU_B)/$(1)/bench/counter.o $(BMCU_B)/$(1)/qemu/startup.o \
            $(BMCU_B)/$(1)/qemu/semihost.o $(BMCU_CORE_SRC:%.c=$(BMCU_B)/$(1)/%.o)

$(BMCU_B)/m0p/bspline.elf: $(call BSMCU_OBJ,m0p) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(BMCU_CPU_m0p) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -o $@ $(filter %.o,$^) -lc -lgcc

$(BMCU_B)/m4f/bspline.elf: $(call BSMCU_OBJ,m4f) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(BMCU_CPU_m4f) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -o $@ $(filter %.o,$^) -lc -lgcc

.PHONY: bench-bspline-mcu
bench-bspline-mcu: $(BMCU_B)/m0p/bspline.elf $(BMCU_B)/m4f/bspline.elf ## B-spline kind: solve/query instructions vs plain float on emulated M0+ and M4F, every magnitude set -> bench/bspline_mcu.json
	@for t in m0p m4f; do \
	  case $$t in m0p) mach=$(BMCU_MACHINE_m0p);; m4f) mach=$(BMCU_MACHINE_m4f);; esac; \
	  timeout --kill-after=5 $(BMCU_TIMEOUT) qemu-system-arm -M $$mach -icount shift=0 -nographic \
	    -monitor none -serial none -semihosting-config enable=on,target=native \
	    -kernel $(BMCU_B)/$$t/bspline.elf </dev/null >$(BMCU_B)/bspline-$$t.log 2>&1 \
	    || { cat $(BMCU_B)/bspline-$$t.log; exit 1; }; \
	done
	@mkdir -p bench
	$(BMCU_PY) $(BMCU_DIR)/bspline_results.py mcu --m0p $(BMCU_B)/bspline-m0p.log \
	  --m4f $(BMCU_B)/bspline-m4f.log --out bench/bspline_mcu.json
	@$(MAKE) --no-print-directory bench-collect

BENCH_TARGETS += bench-bspline-mcu
