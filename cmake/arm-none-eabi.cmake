# Toolchain file for bare-metal Arm Cortex-M with the GNU Arm toolchain
# (Debian: gcc-arm-none-eabi, libnewlib-arm-none-eabi).
#   cmake -S . -B build-m0p --toolchain cmake/arm-none-eabi.cmake
#   cmake ... -DIT2N_ARM_CPU=cortex-m4 -DIT2N_ARM_FLAGS="-mfloat-abi=hard -mfpu=fpv4-sp-d16"
# IT2N_ARM_CPU: -mcpu value, Cortex-M0+ by default. IT2N_ARM_FLAGS: extra
# flags for every compile and link (float ABI, FPU). Both end up in
# CMAKE_C_FLAGS, so a library and the firmware that links it must use the
# same values. IT2N_ARM_PREFIX: tool prefix (default arm-none-eabi-).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(IT2N_ARM_CPU "cortex-m0plus" CACHE STRING "Arm CPU for -mcpu (cortex-m0plus, cortex-m3, cortex-m4, cortex-m7, cortex-m33, ...)")
set(IT2N_ARM_FLAGS "" CACHE STRING "Extra Arm flags (e.g. -mfloat-abi=hard -mfpu=fpv4-sp-d16)")
set(IT2N_ARM_PREFIX "arm-none-eabi-" CACHE STRING "GNU Arm tool prefix")
# try_compile projects see the same choices.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES IT2N_ARM_CPU IT2N_ARM_FLAGS IT2N_ARM_PREFIX)

set(CMAKE_C_COMPILER "${IT2N_ARM_PREFIX}gcc")
set(CMAKE_ASM_COMPILER "${IT2N_ARM_PREFIX}gcc")
set(CMAKE_AR "${IT2N_ARM_PREFIX}ar" CACHE FILEPATH "Archiver")
set(CMAKE_RANLIB "${IT2N_ARM_PREFIX}ranlib" CACHE FILEPATH "Ranlib")
set(CMAKE_OBJCOPY "${IT2N_ARM_PREFIX}objcopy" CACHE FILEPATH "objcopy")
set(CMAKE_SIZE "${IT2N_ARM_PREFIX}size" CACHE FILEPATH "size")
set(CMAKE_NM "${IT2N_ARM_PREFIX}nm" CACHE FILEPATH "nm")

set(CMAKE_C_FLAGS_INIT "-mcpu=${IT2N_ARM_CPU} -mthumb ${IT2N_ARM_FLAGS}")
set(CMAKE_ASM_FLAGS_INIT "-mcpu=${IT2N_ARM_CPU} -mthumb ${IT2N_ARM_FLAGS}")

# Compiler checks link no program (there is no startup code or linker script
# for an arbitrary board).
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
