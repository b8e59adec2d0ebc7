# tests/vectors/: golden core test vectors. One set of scenarios
# (vec_scenarios.c) feeds both the generator, which writes the checked-in
# core_vectors.h from the host library, and the freestanding checker, which
# recomputes and compares bit-exactly on the host (here) and on the emulated
# Cortex-M3 (tests/qemu/). After an intended change of core results:
#   make vectors-regen   and commit tests/vectors/core_vectors.h
VEC_DIR := tests/vectors
VEC_B   := $(BUILD)/vectors
# The checker side is portable code: strict C99 flags like the core.
VEC_PORT_SRC := $(VEC_DIR)/core_vectors.c $(VEC_DIR)/vec_scenarios.c $(VEC_DIR)/vec_paper.c
VEC_HDR := $(VEC_DIR)/vec_scenarios.h $(VEC_DIR)/core_vectors.h $(CORE_HDR)
VEC_CFLAGS := $(CORE_CFLAGS) -I$(VEC_DIR)

$(VEC_B)/host/%.o: $(VEC_DIR)/%.c $(VEC_HDR)
	@mkdir -p $(@D)
	$(CC) $(VEC_CFLAGS) -c $< -o $@

$(VEC_B)/san/%.o: $(VEC_DIR)/%.c $(VEC_HDR)
	@mkdir -p $(@D)
	$(CC) $(VEC_CFLAGS) $(SAN_FLAGS) -c $< -o $@

$(VEC_B)/host_check: $(VEC_DIR)/host_check.c $(VEC_PORT_SRC:$(VEC_DIR)/%.c=$(VEC_B)/host/%.o) $(CORE_LIB)
	$(CC) $(HOST_CFLAGS) $^ -o $@

$(VEC_B)/san_check: $(VEC_DIR)/host_check.c $(VEC_PORT_SRC:$(VEC_DIR)/%.c=$(VEC_B)/san/%.o) $(CORE_SAN_LIB)
	$(CC) $(HOST_CFLAGS) $(SAN_FLAGS) $^ -o $@

$(VEC_B)/gen_vectors: $(VEC_DIR)/gen_vectors.c $(VEC_B)/host/vec_scenarios.o $(VEC_B)/host/vec_paper.o $(CORE_LIB)
	$(CC) $(HOST_CFLAGS) -I$(VEC_DIR) $^ -o $@

.PHONY: vectors-host vectors-san vectors-current vectors-regen
vectors-host: $(VEC_B)/host_check
	$<

vectors-san: $(VEC_B)/san_check
	$<

# The checked-in header must be what the current core produces.
vectors-current: $(VEC_B)/gen_vectors
	$< examples/paper_4x4.csv $(VEC_B)/core_vectors.h.new
	@cmp -s $(VEC_B)/core_vectors.h.new $(VEC_DIR)/core_vectors.h || { \
	  diff -u $(VEC_DIR)/core_vectors.h $(VEC_B)/core_vectors.h.new | head -40; \
	  echo "vectors-current: $(VEC_DIR)/core_vectors.h is stale: core results changed." >&2; \
	  echo "  If the change is intended: make vectors-regen, review, commit the header." >&2; \
	  exit 1; }
	@echo "vectors-current: $(VEC_DIR)/core_vectors.h matches the core"

vectors-regen: $(VEC_B)/gen_vectors ## Regenerate tests/vectors/core_vectors.h after an intended core change
	$< examples/paper_4x4.csv $(VEC_DIR)/core_vectors.h

TEST_TARGETS += vectors-host vectors-san vectors-current
