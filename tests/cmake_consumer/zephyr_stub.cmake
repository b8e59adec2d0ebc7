# Runs zephyr/CMakeLists.txt without Zephyr (cmake -P): the zephyr_* commands
# are stubs that record what the module asks for, and the CONFIG_* values
# are those of tests/core/config/it2n_test_config.h, so that
# tests/core/test_config.c can check the generated IT2N_CONFIG header.
#   cmake -DOUT=dir -P tests/cmake_consumer/zephyr_stub.cmake
# Writes OUT/sources.txt, OUT/includes.txt, OUT/defines.txt (one per line)
# and the generated header under OUT.
cmake_minimum_required(VERSION 3.20) # Zephyr's own minimum: same policies
if(NOT OUT)
  message(FATAL_ERROR "usage: cmake -DOUT=dir -P zephyr_stub.cmake")
endif()
set(CMAKE_CURRENT_BINARY_DIR "${OUT}")
file(REMOVE "${OUT}/sources.txt" "${OUT}/includes.txt" "${OUT}/defines.txt")
file(TOUCH "${OUT}/sources.txt" "${OUT}/includes.txt" "${OUT}/defines.txt")

set(CONFIG_IT2N y)
set(CONFIG_IT2N_PROTOCOL y)
set(CONFIG_IT2N_MAX_DEGREE 3)
set(CONFIG_IT2N_COORD_LIMIT 1000)
# CONFIG_IT2N_CHORD=n: Kconfig leaves the variable undefined
set(CONFIG_IT2N_LOCATE_MAX_ITER 20)
set(CONFIG_IT2N_LOCATE_GRID 4)
set(CONFIG_IT2N_BSPLINE_MAX_N 15)
set(CONFIG_IT2N_ASSERT y)

function(_it2n_record file)
  foreach(a IN LISTS ARGN)
    file(APPEND "${OUT}/${file}" "${a}\n")
  endforeach()
endfunction()
function(zephyr_library_named name)
  file(WRITE "${OUT}/library.txt" "${name}\n")
endfunction()
function(zephyr_library_sources)
  _it2n_record(sources.txt ${ARGN})
endfunction()
function(zephyr_library_sources_ifdef opt)
  if(${opt})
    _it2n_record(sources.txt ${ARGN})
  endif()
endfunction()
function(zephyr_include_directories)
  _it2n_record(includes.txt ${ARGN})
endfunction()
function(zephyr_include_directories_ifdef opt)
  if(${opt})
    _it2n_record(includes.txt ${ARGN})
  endif()
endfunction()
function(zephyr_compile_definitions)
  _it2n_record(defines.txt ${ARGN})
endfunction()

include("${CMAKE_CURRENT_LIST_DIR}/../../zephyr/CMakeLists.txt")
