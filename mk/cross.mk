# Portability proof (issue 2): `make cross` builds firmware_core/*.c and
# protocol/*.c with arm-none-eabi-gcc for Cortex-M0+ and Cortex-M4 (soft
# float, freestanding) and rejects heap, floating-point and libc references;
# `make size` prints flash, static RAM, worst-case stack and struct sizes.
# Tools live in tests/qemu/ (symcheck.sh, stack_report.py); see
# docs/portability.md.

CROSS_CC   := arm-none-eabi-gcc
CROSS_NM   := arm-none-eabi-nm
CROSS_SIZE := arm-none-eabi-size
CROSS_DIR  := $(BUILD)/cross
CROSS_TOOLS := tests/qemu

CROSS_SRC := $(CORE_SRC) $(PROTO_SRC)
CROSS_HDR = $(wildcard firmware_core/*.h) $(wildcard protocol/*.h) $(wildcard protocol/*.inc)
CROSS_CFLAGS := -ffreestanding -std=c99 -Os -g $(CORE_WARN) \
                -ffunction-sections -fdata-sections -fstack-usage -fcallgraph-info=su \
                -Ifirmware_core -Iprotocol

# Known violations tolerated (with a warning) until their owner fixes them;
# heap and float references can never be waived. Keep this empty.
CROSS_WAIVE :=

# m0p_d3: the small-part configuration (IT2N_MAX_DEGREE=3) on Cortex-M0+,
# which also proves a non-default configuration builds warning-free.
CROSS_ARCHS := m0p m4 m0p_d3
CROSS_CPU_m0p := -mcpu=cortex-m0plus -mthumb
CROSS_CPU_m4  := -mcpu=cortex-m4 -mthumb
CROSS_CPU_m0p_d3 := -mcpu=cortex-m0plus -mthumb
CROSS_DEF_m0p_d3 := -DIT2N_MAX_DEGREE=3
CROSS_NAME_m0p := Cortex-M0+
CROSS_NAME_m4  := Cortex-M4 (soft float)
CROSS_NAME_m0p_d3 := Cortex-M0+ MAX_DEGREE=3

# Per target: objects (+ .su/.ci next to them), a partial link of the whole
# library (what symcheck inspects) and a full link from api_refs.c.
define CROSS_ARCH_RULES
CROSS_OBJ_$(1) = $$(CROSS_SRC:%.c=$(CROSS_DIR)/$(1)/%.o)

$(CROSS_DIR)/$(1)/%.o: %.c $$(CROSS_HDR)
	@mkdir -p $$(@D)
	$(CROSS_CC) $(CROSS_CPU_$(1)) $(CROSS_DEF_$(1)) $(CROSS_CFLAGS) -c $$< -o $$@

$(CROSS_DIR)/$(1)/libit2n-r.o: $$(CROSS_OBJ_$(1))
	$(CROSS_CC) $(CROSS_CPU_$(1)) -nostdlib -r -o $$@ $$^

$(CROSS_DIR)/$(1)/api_refs.o: $(CROSS_TOOLS)/api_refs.c $$(CROSS_HDR)
	@mkdir -p $$(@D)
	$(CROSS_CC) $(CROSS_CPU_$(1)) $(CROSS_DEF_$(1)) $(CROSS_CFLAGS) -c $$< -o $$@

# Symbols are checked first, so -lc can only supply memcpy/memset/memmove.
$(CROSS_DIR)/$(1)/it2n-api.elf: $(CROSS_DIR)/$(1)/api_refs.o $(CROSS_DIR)/$(1)/libit2n-r.o
	SYMCHECK_WAIVE="$(CROSS_WAIVE)" $(CROSS_TOOLS)/symcheck.sh $(CROSS_NM) $(CROSS_SIZE) \
	  "$$$$($(CROSS_CC) $(CROSS_CPU_$(1)) -print-libgcc-file-name)" $(CROSS_DIR)/$(1)/libit2n-r.o
	$(CROSS_CC) $(CROSS_CPU_$(1)) -nostdlib -Wl,--gc-sections -Wl,-e,it2n_cross_entry \
	  -o $$@ $$^ -lc -lgcc

.PHONY: cross-$(1)
cross-$(1): $(CROSS_DIR)/$(1)/it2n-api.elf
endef
$(foreach a,$(CROSS_ARCHS),$(eval $(call CROSS_ARCH_RULES,$(a))))

cross: $(CROSS_ARCHS:%=cross-%) ## Cross-build core+protocol for Cortex-M0+/M4; fail on heap/float/libc use
	@echo "cross: $(CROSS_ARCHS) clean: no heap, no floating point, no libc beyond memcpy/memset/memmove$(if $(CROSS_WAIVE), (waived: $(CROSS_WAIVE)))"

# The checker must reject what it claims to reject (and accept clean code).
.PHONY: cross-selftest
cross-selftest:
	@$(CROSS_TOOLS)/symcheck_selftest.sh $(CROSS_DIR)/selftest $(CROSS_CC) $(CROSS_NM) \
	  $(CROSS_SIZE) "$(CROSS_CFLAGS)" "$(CROSS_CPU_m0p)" "$(CROSS_CPU_m4)"

TEST_TARGETS += cross-selftest cross

# ---- make size -------------------------------------------------------------

# sizeof of the public structs, read back as symbol sizes (nm -S) of arrays
# declared in sizes.c, for the default configuration and IT2N_MAX_DEGREE=3.
$(CROSS_DIR)/sizes-%.o: $(CROSS_TOOLS)/sizes.c $(CORE_HDR)
	@mkdir -p $(@D)
	$(CROSS_CC) $(CROSS_CPU_m4) -std=c99 -fno-common $(if $(filter d3,$*),-DIT2N_MAX_DEGREE=3) \
	  -Ifirmware_core -c $< -o $@

$(CROSS_DIR)/sizes-host.o: $(CROSS_TOOLS)/sizes.c $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) -std=c99 -fno-common -Ifirmware_core -c $< -o $@

# Host build of the core with stack usage, for the daemon/CLI figure.
CROSS_HOST_OBJ = $(CORE_SRC:%.c=$(CROSS_DIR)/host/%.o)
$(CROSS_DIR)/host/%.o: %.c $(CORE_HDR)
	@mkdir -p $(@D)
	$(CC) $(CORE_CFLAGS) -fstack-usage -fcallgraph-info=su -c $< -o $@

# Public functions: global text symbols ($(1) = nm, $(2) = objects) that a
# public header (it2n.h, protocol/*.h) declares; it2n__* and it2n_fixed.h
# helpers are internal.
CROSS_PUB_HDR = firmware_core/it2n.h $(wildcard protocol/*.h)
CROSS_PUBLIC = $(1) --defined-only -g $(2) | awk '$$2 == "T" {print $$3}' | sort -u | \
  grep -xF -f <(grep -ohE '\<it2n_[a-z0-9_]+ *\(' $(CROSS_PUB_HDR) | tr -d '( ' | sort -u)

SIZE_DEPS = $(CROSS_ARCHS:%=cross-%) $(CROSS_HOST_OBJ) $(CROSS_DIR)/sizes-default.o $(CROSS_DIR)/sizes-d3.o \
  $(CROSS_DIR)/sizes-host.o
# docfig.py (docs-check, docs-figures; tests/docs/docs.mk) runs `make size`:
# what it reads is built beforehand, by make test's prerequisite step, and
# not by the make inside the suite while other suites share the machine
# (the cross builds, not the cross suite: a suite after another runs alone).
docs-check docs-figures: $(SIZE_DEPS)
size: $(SIZE_DEPS) ## Flash, static RAM, worst-case stack per target; struct sizes
	@echo "== Flash and static RAM, bytes (core + protocol, every function kept; last column:"
	@echo "   text of a --gc-sections link of the whole core API with libgcc and newlib's mem*) =="
	@printf '  %-24s %12s %10s %12s %18s\n' target "text+rodata" "data+bss" "(core only)" "linked, core API"
	@for a in $(CROSS_ARCHS); do \
	  name=$$a; case $$a in m0p) name="$(CROSS_NAME_m0p)";; m4) name="$(CROSS_NAME_m4)";; m0p_d3) name="$(CROSS_NAME_m0p_d3)";; esac; \
	  core=$$($(CROSS_SIZE) -A $(CROSS_DIR)/$$a/firmware_core/*.o | awk '$$1 ~ /^\.(text|rodata)/ {f += $$2} END {print f}'); \
	  $(CROSS_SIZE) -A $(CROSS_DIR)/$$a/libit2n-r.o | awk -v n="$$name" -v core=$$core -v elf="$$($(CROSS_SIZE) -B $(CROSS_DIR)/$$a/it2n-api.elf | awk 'NR==2 {print $$1}')" \
	    '$$1 ~ /^\.(text|rodata)/ {f += $$2} $$1 ~ /^\.(data|bss)/ {r += $$2} \
	     END {printf "  %-24s %12d %10d %12d %18d\n", n, f, r, core, elf}'; \
	done
	@for a in $(CROSS_ARCHS); do \
	  name=$$a; case $$a in m0p) name="$(CROSS_NAME_m0p)";; m4) name="$(CROSS_NAME_m4)";; m0p_d3) name="$(CROSS_NAME_m0p_d3)";; esac; \
	  echo; $(call CROSS_PUBLIC,$(CROSS_NM),$(CROSS_DIR)/$$a/libit2n-r.o) > $(CROSS_DIR)/$$a/public.txt; \
	  python3 $(CROSS_TOOLS)/stack_report.py "$$name, -Os" $(CROSS_DIR)/$$a/public.txt \
	    $$(find $(CROSS_DIR)/$$a -name '*.ci' | sort) || exit 1; \
	done
	@echo; $(call CROSS_PUBLIC,nm,$(CROSS_HOST_OBJ)) > $(CROSS_DIR)/host/public.txt
	@python3 $(CROSS_TOOLS)/stack_report.py "host $(CC) -O2 (core only)" $(CROSS_DIR)/host/public.txt \
	  $$(find $(CROSS_DIR)/host -name '*.ci' | sort)
	@echo; echo "== sizeof (bytes) =="
	@printf '  %-22s %12s %18s %14s\n' struct "ARM default" "ARM MAX_DEGREE=3" "x86-64 default"
	@for s in dataset model point locate_result errinfo; do \
	  sz() { nm -S $$1 | awk -v s=it2n_sizeof_$$s '$$4 == s {print $$2}'; }; \
	  printf '  %-22s %12d %18d %14d\n' it2n_$$s 0x$$(sz $(CROSS_DIR)/sizes-default.o) \
	    0x$$(sz $(CROSS_DIR)/sizes-d3.o) 0x$$(sz $(CROSS_DIR)/sizes-host.o); \
	done
