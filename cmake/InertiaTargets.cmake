# Compile options every inertia target shares.
add_library(inertia_warnings INTERFACE)
target_compile_options(inertia_warnings INTERFACE -Wall -Wextra -Wpedantic
                       $<$<BOOL:${INERTIA_WERROR}>:-Werror>)
# INERTIA_SANITIZE takes one sanitizer or a comma list ("address,undefined"). UBSan is built
# with -fno-sanitize-recover: a report aborts the test that caused it, so CI cannot pass over one.
if(INERTIA_SANITIZE)
  add_compile_options(-fsanitize=${INERTIA_SANITIZE} -fno-omit-frame-pointer)
  add_link_options(-fsanitize=${INERTIA_SANITIZE})
  if(INERTIA_SANITIZE MATCHES "undefined")
    add_compile_options(-fno-sanitize-recover=undefined)
    add_link_options(-fno-sanitize-recover=undefined)
    # GCC 12's -fsanitize=undefined breaks LCM's C++ subscriptions: the callbacks of
    # lcm-cpp-impl.hpp (LCMMHSubscription::cb_func) get a wrong `this` and crash or report a
    # misaligned LCMMHUntypedSubscription in every test that receives over LCM. A 15-line
    # program with no code of ours does it too; dropping any one of vptr, null or alignment
    # cures it, clang's UBSan is fine. vptr (the dynamic type of a polymorphic object) goes,
    # with GCC only: ASan still catches a freed or too small object, and the fuzz build (clang)
    # keeps vptr.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      add_compile_options(-fno-sanitize=vptr)
    endif()
  endif()
endif()

# INERTIA_FUZZ: the libFuzzer targets of tests/fuzz. libFuzzer ships with clang only.
# Every library is compiled with the fuzzer's coverage hooks and ASan+UBSan; build only the
# fuzz targets in such a tree (cmake --build build-fuzz --target fuzz_model_file ...), so only
# the libraries they link are compiled.
option(INERTIA_FUZZ "Build the libFuzzer targets in tests/fuzz (clang only)" OFF)
if(INERTIA_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "INERTIA_FUZZ needs clang (libFuzzer): configure with -DCMAKE_CXX_COMPILER=clang++")
  endif()
  if(INERTIA_SANITIZE)
    message(FATAL_ERROR "INERTIA_FUZZ already builds with address,undefined: leave INERTIA_SANITIZE empty")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
                      -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined -fno-sanitize-recover=undefined)
endif()

# In a unity build every source is #included into a batch file, so GCC takes each one for a
# header and -Wsubobject-linkage ("a field whose type uses the anonymous namespace") fires on
# every source-local Impl holding a file-local type: a finding about headers that does not apply.
# The file-by-file build keeps the warning.
if(CMAKE_UNITY_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  target_compile_options(inertia_warnings INTERFACE -Wno-subobject-linkage)
endif()

# inertia_add_library(name SOURCES ... DEPENDS ...): a static library rooted at the source tree,
# so includes read "common/units.hpp", "analyzer/ident/uls_batch.hpp".
function(inertia_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR}/generated)
  target_link_libraries(${name} PUBLIC ${ARG_DEPENDS} PRIVATE inertia_warnings)
endfunction()

# The test binaries' heavy headers (GoogleTest, Eigen, the standard library's), precompiled once
# into inertia_test_pch and reused by every test target: parsed once per build instead of once
# per test file. GCC takes a precompiled header only when the flags it was made with match (the
# sanitizer's, -march, the definitions below), and otherwise reads the headers as text: a mismatch
# costs time, never correctness. Off: each test file parses them itself.
option(INERTIA_TEST_PCH "Precompile the test binaries' common headers once" ON)
set(INERTIA_TEST_DEFINITIONS INERTIA_SOURCE_DIR="${PROJECT_SOURCE_DIR}" INERTIA_BINARY_DIR="${PROJECT_BINARY_DIR}")
if(INERTIA_TEST_PCH AND NOT INERTIA_FUZZ)
  add_library(inertia_test_pch STATIC ${PROJECT_SOURCE_DIR}/tests/support/pch_anchor.cpp)
  target_link_libraries(inertia_test_pch PRIVATE GTest::gtest Eigen3::Eigen inertia_warnings)
  target_compile_definitions(inertia_test_pch PRIVATE ${INERTIA_TEST_DEFINITIONS})
  target_precompile_headers(inertia_test_pch PRIVATE
    <gtest/gtest.h> <Eigen/Dense> <algorithm> <chrono> <cmath> <filesystem> <fstream> <functional> <map>
    <memory> <optional> <random> <set> <sstream> <string> <thread> <vector>)
endif()

# inertia_add_gtest(name SOURCES ... DEPENDS ... [LABELS ...]): one GoogleTest binary, each test a CTest test.
function(inertia_add_gtest name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  # UNITY_BUILD OFF: each test file reads alone, its helpers in an anonymous namespace under the
  # names that suit it (kSmall, line_of in several daemon tests), so the files of one test binary
  # are never merged into one unity source (CI builds the sanitizer jobs' libraries that way).
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/tests UNITY_BUILD OFF)
  target_link_libraries(${name} PRIVATE ${ARG_DEPENDS} GTest::gtest_main inertia_warnings)
  target_compile_definitions(${name} PRIVATE ${INERTIA_TEST_DEFINITIONS})
  if(TARGET inertia_test_pch)
    target_precompile_headers(${name} REUSE_FROM inertia_test_pch)
  endif()
  # Labels go on the directory (every test folder holds one area): a list passed through
  # gtest_discover_tests' PROPERTIES keeps only its first element in CMake 3.25.
  set_property(DIRECTORY APPEND PROPERTY LABELS ${ARG_LABELS})
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60)
endfunction()

# inertia_add_benchmark(name SOURCES ... DEPENDS ...): a Google Benchmark binary in build/bench.
function(inertia_add_benchmark name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
  target_link_libraries(${name} PRIVATE ${ARG_DEPENDS} benchmark::benchmark_main inertia_warnings)
endfunction()
