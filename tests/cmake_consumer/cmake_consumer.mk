# tests/cmake_consumer/: the drop-in library for firmware builds (issue 10).
#   cmake-consumer  the top-level CMakeLists.txt installs it2n into temporary
#                   prefixes (host; Cortex-M0+ with cmake/arm-none-eabi.cmake
#                   and an IT2N_CONFIG header); an out-of-tree project uses it
#                   through find_package(it2n) and pkg-config: the host program
#                   runs and must print what `it2n eval` prints, the M0+
#                   image must link freestanding without heap/float symbols
#   dropin-check    Zephyr module and PlatformIO manifest: listed files exist,
#                   sources = the Makefile's, Kconfig = it2n.h's options (and
#                   the Kconfig-generated IT2N_CONFIG header builds the core
#                   with them); docs/firmware.md quotes its example verbatim
# See docs/firmware.md. (The plain-Makefile example is Makefile.firmware, not
# *.mk: tests/tests.mk includes every tests/*/*.mk.)
DEB_PACKAGES += cmake

.PHONY: cmake-consumer dropin-check
cmake-consumer: $(BUILD)/host/it2n ## Build an out-of-tree find_package(it2n) project for host and Cortex-M0+
	@tests/cmake_consumer/run.sh $(BUILD)/host/it2n

dropin-check: ## Check the Zephyr module, PlatformIO manifest and docs/firmware.md quotes
	@/usr/bin/python3 tests/cmake_consumer/check_dropin.py
	@tests/cmake_consumer/zephyr_stub.sh $(CC) -std=c99 -O2 $(CORE_WARN)

TEST_TARGETS += cmake-consumer dropin-check
