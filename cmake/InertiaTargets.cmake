# Compile options every inertia target shares.
add_library(inertia_warnings INTERFACE)
target_compile_options(inertia_warnings INTERFACE -Wall -Wextra -Wpedantic
                       $<$<BOOL:${INERTIA_WERROR}>:-Werror>)
if(INERTIA_SANITIZE)
  add_compile_options(-fsanitize=${INERTIA_SANITIZE} -fno-omit-frame-pointer)
  add_link_options(-fsanitize=${INERTIA_SANITIZE})
endif()

# inertia_add_library(name SOURCES ... DEPENDS ...): a static library rooted at the source tree,
# so includes read "common/units.hpp", "analyzer/ident/uls_batch.hpp".
function(inertia_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR}/generated)
  target_link_libraries(${name} PUBLIC ${ARG_DEPENDS} PRIVATE inertia_warnings)
endfunction()

# inertia_add_gtest(name SOURCES ... DEPENDS ... [LABELS ...]): one GoogleTest binary, each test a CTest test.
function(inertia_add_gtest name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/tests)
  target_link_libraries(${name} PRIVATE ${ARG_DEPENDS} GTest::gtest_main inertia_warnings)
  target_compile_definitions(${name} PRIVATE INERTIA_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                             INERTIA_BINARY_DIR="${PROJECT_BINARY_DIR}")
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
