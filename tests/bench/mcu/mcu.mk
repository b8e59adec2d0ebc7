# tests/bench/mcu/: issue 7's benchmark. The it2n core against plain float
# and double baselines on the same data (paper 4x4, smooth 7x7):
#   qemu-system-arm -icount shift=0, timer read before/after each operation
#   (counter validated on a loop of known length in the same run):
#     m0p  ARMv6-M code (-mcpu=cortex-m0plus, -Os, as make cross) on mps2-an385
#     m4f  ARMv7E-M+FPU code (-mcpu=cortex-m4 -mfloat-abi=hard, -O2) on mps2-an386
#   host (x86-64 -O2): time per query in interleaved rounds until the
#   it2n/double interval is within +-5 % (host_rounds.py, at most 30),
#   callgrind instructions, accuracy
#   against tests/core/ref.c, baselines checked against it2n;
#   struct sizes (IT2N_MAX_DEGREE 3 and 7), core flash of solve+eval+locate.
# bench-mcu writes bench/mcu.json, then bench/results.json and docs/performance.md (bench-collect)
# (BENCH_QUICK=1: fewer points and repetitions); bench-mcu-smoke (make test)
# checks the harness works and docs/performance.md matches the JSON, and
# asserts no timing.
BMCU_DIR := tests/bench/mcu
BMCU_B := $(BUILD)/bench/mcu
BMCU_PY := /usr/bin/python3
BMCU_TIMEOUT ?= 600
BMCU_MODE = $(if $(BENCH_QUICK),quick,full)
BMCU_HDR = $(wildcard $(BMCU_DIR)/*.h) $(CORE_HDR) tests/qemu/semihost.h
BMCU_CORE_SRC = $(CORE_SRC)

$(BMCU_B)/datasets.c: $(BMCU_DIR)/datasets.py examples/paper_4x4.csv
	@mkdir -p $(@D)
	$(BMCU_PY) $< examples/paper_4x4.csv $@

# ---- images ------------------------------------------------------------------
BMCU_IMG_SRC := $(addprefix $(BMCU_DIR)/,driver.c entry.c counter.c stack_probe.c report.c \
                it2n_calls.c baseline_float.c baseline_double.c) \
                tests/qemu/startup.c tests/qemu/semihost.c
BMCU_CPU_m0p := -mcpu=cortex-m0plus -mthumb
BMCU_CPU_m4f := -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16
BMCU_CPU_m0p_d3 := $(BMCU_CPU_m0p)
BMCU_CPU_m0p_d3u := $(BMCU_CPU_m0p)
BMCU_OPT_m0p := -Os
BMCU_OPT_m4f := -O2
BMCU_OPT_m0p_d3 := -Os
BMCU_OPT_m0p_d3u := -Os
BMCU_DEF_m0p_d3 := -DIT2N_MAX_DEGREE=3
# the same without chord-length parameters (IT2N_CHORD=0)
BMCU_DEF_m0p_d3u := -DIT2N_MAX_DEGREE=3 -DIT2N_CHORD=0
BMCU_MACHINE_m0p := mps2-an385
BMCU_MACHINE_m4f := mps2-an386
# The core exactly as make cross builds it (CROSS_CFLAGS), at this target's
# optimisation level; the benchmark code with the same warnings.
BMCU_CORE_CFLAGS = $(filter-out -Os -O2,$(CROSS_CFLAGS))
BMCU_CFLAGS = -ffreestanding -std=c99 -g $(CORE_WARN) -ffunction-sections -fdata-sections \
              -Ifirmware_core -I$(BMCU_DIR) -Itests/qemu

define BMCU_TARGET_RULES
$(BMCU_B)/$(1)/firmware_core/%.o: firmware_core/%.c $$(CORE_HDR)
	@mkdir -p $$(@D)
	arm-none-eabi-gcc $(BMCU_CPU_$(1)) $(BMCU_OPT_$(1)) $(BMCU_DEF_$(1)) $$(BMCU_CORE_CFLAGS) -c $$< -o $$@

$(BMCU_B)/$(1)/bench/%.o: $(BMCU_DIR)/%.c $$(BMCU_HDR)
	@mkdir -p $$(@D)
	arm-none-eabi-gcc $(BMCU_CPU_$(1)) $(BMCU_OPT_$(1)) $(BMCU_DEF_$(1)) $$(BMCU_CFLAGS) -c $$< -o $$@

$(BMCU_B)/$(1)/qemu/%.o: tests/qemu/%.c $$(BMCU_HDR)
	@mkdir -p $$(@D)
	arm-none-eabi-gcc $(BMCU_CPU_$(1)) $(BMCU_OPT_$(1)) $$(BMCU_CFLAGS) -c $$< -o $$@

$(BMCU_B)/$(1)/bench/datasets.o: $(BMCU_B)/datasets.c $$(BMCU_HDR)
	@mkdir -p $$(@D)
	arm-none-eabi-gcc $(BMCU_CPU_$(1)) $(BMCU_OPT_$(1)) $$(BMCU_CFLAGS) -c $$< -o $$@
endef
$(foreach t,m0p m4f m0p_d3 m0p_d3u,$(eval $(call BMCU_TARGET_RULES,$(t))))

BMCU_IMG_OBJ = $(patsubst $(BMCU_DIR)/%.c,$(BMCU_B)/$(1)/bench/%.o,$(patsubst tests/qemu/%.c,$(BMCU_B)/$(1)/qemu/%.o,$(BMCU_IMG_SRC))) \
               $(BMCU_B)/$(1)/bench/datasets.o $(BMCU_CORE_SRC:%.c=$(BMCU_B)/$(1)/%.o)

$(BMCU_B)/m0p/bench.elf: $(call BMCU_IMG_OBJ,m0p) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(BMCU_CPU_m0p) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-Map=$(@:.elf=.map) -o $@ $(filter %.o,$^) -lc -lgcc

$(BMCU_B)/m4f/bench.elf: $(call BMCU_IMG_OBJ,m4f) tests/qemu/mps2_an385.ld
	arm-none-eabi-gcc $(BMCU_CPU_m4f) -nostdlib -T tests/qemu/mps2_an385.ld -Wl,--gc-sections \
	  -Wl,-Map=$(@:.elf=.map) -o $@ $(filter %.o,$^) -lc -lgcc

# Run an image: $(1) target, $(2) mode (full, quick, smoke), $(3) log.
BMCU_RUN = timeout --kill-after=5 $(BMCU_TIMEOUT) qemu-system-arm -M $(BMCU_MACHINE_$(1)) \
  -icount shift=0 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native,arg=bench,arg=$(2) \
  -kernel $(BMCU_B)/$(1)/bench.elf </dev/null >$(3).tmp 2>&1 \
  || { cat $(3).tmp; echo "bench: $(1) image failed" >&2; exit 1; }; mv $(3).tmp $(3)

# ---- flash: solve + eval + locate, M0+, IT2N_MAX_DEGREE=3 --------------------
$(BMCU_B)/m0p_d3/flash.elf: $(BMCU_B)/m0p_d3/bench/flash_entry.o $(BMCU_CORE_SRC:%.c=$(BMCU_B)/m0p_d3/%.o)
	arm-none-eabi-gcc $(BMCU_CPU_m0p) -nostdlib -Wl,--gc-sections -Wl,-e,bc_flash_entry \
	  -Wl,-Map=$(@:.elf=.map) -o $@ $^ -lc -lgcc

$(BMCU_B)/m0p_d3u/flash.elf: $(BMCU_B)/m0p_d3u/bench/flash_entry.o $(BMCU_CORE_SRC:%.c=$(BMCU_B)/m0p_d3u/%.o)
	arm-none-eabi-gcc $(BMCU_CPU_m0p) -nostdlib -Wl,--gc-sections -Wl,-e,bc_flash_entry \
	  -Wl,-Map=$(@:.elf=.map) -o $@ $^ -lc -lgcc

# ---- struct sizes: tests/qemu/sizes.c for both configurations ---------------
$(BMCU_B)/sizes-%.o: tests/qemu/sizes.c $(CORE_HDR)
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(BMCU_CPU_m0p) -std=c99 -fno-common $(if $(filter d3,$*),-DIT2N_MAX_DEGREE=3) \
	  -Ifirmware_core -c $< -o $@

$(BMCU_B)/sizes.txt: $(BMCU_B)/sizes-d3.o $(BMCU_B)/sizes-d7.o
	@for c in d3 d7; do arm-none-eabi-nm -S -t d $(BMCU_B)/sizes-$$c.o | \
	  awk -v c=$$c '$$4 ~ /^it2n_sizeof_(model|dataset)$$/ {sub(/^it2n_sizeof_/, "", $$4); \
	    printf "R sizes.%s.%s %d\n", c, $$4, $$2 + 0}'; done > $@

# ---- host program ------------------------------------------------------------
BMCU_HOST_FW := $(addprefix $(BMCU_DIR)/,it2n_calls.c baseline_float.c baseline_double.c)
BMCU_HOST_OBJ = $(BMCU_HOST_FW:$(BMCU_DIR)/%.c=$(BMCU_B)/host/%.o) $(BMCU_B)/host/datasets.o

$(BMCU_B)/host/%.o: $(BMCU_DIR)/%.c $(BMCU_HDR)
	@mkdir -p $(@D)
	$(CC) -std=c99 -O2 -g $(CORE_WARN) -DBENCH_HOST -Ifirmware_core -I$(BMCU_DIR) -c $< -o $@

$(BMCU_B)/host/datasets.o: $(BMCU_B)/datasets.c $(BMCU_HDR)
	@mkdir -p $(@D)
	$(CC) -std=c99 -O2 -g $(CORE_WARN) -DBENCH_HOST -Ifirmware_core -I$(BMCU_DIR) -c $< -o $@

$(BMCU_B)/host/bench_host: $(BMCU_DIR)/host.c tests/core/ref.c tests/core/ref.h $(BMCU_HOST_OBJ) $(CORE_LIB)
	$(CC) $(HOST_CFLAGS) -DBENCH_HOST -I$(BMCU_DIR) -Itests/core $(BMCU_DIR)/host.c tests/core/ref.c \
	  $(BMCU_HOST_OBJ) $(CORE_LIB) -lm -o $@

# callgrind: instructions of BC_NPTS_MAX queries inside cg_queries.
BMCU_CG = valgrind --tool=callgrind --toggle-collect=cg_queries --callgrind-out-file=$(BMCU_B)/cg-$(1)-$(2).out \
  $(BMCU_B)/host/bench_host cg $(1) $(2) >/dev/null 2>&1 && \
  awk -v k="$(2).cg.$(1)" '/^(summary|totals):/ {print "R " k " " $$2; exit}' $(BMCU_B)/cg-$(1)-$(2).out >> $(3)

# ---- the benchmark -----------------------------------------------------------
BMCU_ALL := $(BMCU_B)/m0p/bench.elf $(BMCU_B)/m4f/bench.elf $(BMCU_B)/m0p_d3/flash.elf \
            $(BMCU_B)/m0p_d3u/flash.elf \
            $(BMCU_B)/host/bench_host $(BMCU_B)/sizes.txt

.PHONY: bench-mcu bench-mcu-smoke
bench-mcu: $(BMCU_ALL)
	@echo "== bench-mcu ($(BMCU_MODE)): qemu M0+ =="
	@$(call BMCU_RUN,m0p,$(BMCU_MODE),$(BMCU_B)/m0p.log)
	@echo "== bench-mcu: qemu M4F =="
	@$(call BMCU_RUN,m4f,$(BMCU_MODE),$(BMCU_B)/m4f.log)
	@echo "== bench-mcu: host check, timing, callgrind =="
	@$(BMCU_B)/host/bench_host check > $(BMCU_B)/host.log || { cat $(BMCU_B)/host.log; exit 1; }
	@$(BMCU_PY) $(BMCU_DIR)/host_rounds.py $(BMCU_B)/host/bench_host $(if $(BENCH_QUICK),8 quick,30) \
	  > $(BMCU_B)/x86.log
	@: > $(BMCU_B)/cg.log; for s in paper4 smooth7; do for i in it2n double; do \
	  $(call BMCU_CG,$$i,$$s,$(BMCU_B)/cg.log) || exit 1; done; done
	@mkdir -p bench
	$(BMCU_PY) $(BMCU_DIR)/results.py --mode $(BMCU_MODE) --m0p $(BMCU_B)/m0p.log --m4f $(BMCU_B)/m4f.log \
	  --host $(BMCU_B)/host.log $(BMCU_B)/x86.log $(BMCU_B)/cg.log $(BMCU_B)/sizes.txt \
	  --flash-map $(BMCU_B)/m0p_d3/flash.map --flash-map-uniform $(BMCU_B)/m0p_d3u/flash.map --out bench/mcu.json
	@$(MAKE) --no-print-directory bench-collect

BENCH_TARGETS += bench-mcu
# Under `make bench`, bench-mcu (its x86-64 times) runs after every other
# benchmark: the rule is in the Makefile, after all of BENCH_TARGETS is known.

# Smoke (make test): the images run a few points, the host checks the
# baselines; results.py --smoke fails on a counter off by > 1 %, baselines
# that disagree with it2n, results differing between targets, or malformed
# JSON, never on a ratio or a time (bench-results-check compares the
# committed bench/results.json and docs/performance.md with bench/*.json).
bench-mcu-smoke: $(BMCU_ALL)
	@mkdir -p $(BMCU_B)/smoke
	@$(call BMCU_RUN,m0p,smoke,$(BMCU_B)/smoke/m0p.log)
	@$(call BMCU_RUN,m4f,smoke,$(BMCU_B)/smoke/m4f.log)
	@$(BMCU_B)/host/bench_host check smoke > $(BMCU_B)/smoke/host.log || { cat $(BMCU_B)/smoke/host.log; exit 1; }
	@$(BMCU_PY) $(BMCU_DIR)/results.py --smoke --mode smoke --m0p $(BMCU_B)/smoke/m0p.log \
	  --m4f $(BMCU_B)/smoke/m4f.log --host $(BMCU_B)/smoke/host.log $(BMCU_B)/sizes.txt \
	  --flash-map $(BMCU_B)/m0p_d3/flash.map --flash-map-uniform $(BMCU_B)/m0p_d3u/flash.map --out $(BMCU_B)/smoke/results.json

TEST_TARGETS += bench-mcu-smoke
