#pragma once
// Bench-file unit tests: a bench text written to a scratch file per test, loaded, and the
// InputError it raises with the line it names.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"

namespace inertia::config::testing {

class BenchFileTest : public ::testing::Test {
 protected:
  std::filesystem::path write(const std::string& text) {
    const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                      ("inertia_bench_file_" + std::to_string(::getpid()) + "_" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir);
    const std::filesystem::path p = dir / "bench.toml";
    std::ofstream(p) << text;
    return p;
  }
  /// The InputError loading `text` raises (a test failure when it loads).
  InputError error_of(const std::string& text) {
    try {
      (void)load_bench_config(write(text));
    } catch (const InputError& e) {
      return e;
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return InputError("none");
  }
  /// 1-based line of the n-th (1-based) line of `text` starting with `prefix`.
  static std::size_t line_of(const std::string& text, const std::string& prefix, int nth = 1) {
    std::istringstream in(text);
    std::string line;
    for (std::size_t n = 1; std::getline(in, line); ++n)
      if (line.rfind(prefix, 0) == 0 && --nth == 0) return n;
    return 0;
  }
};

}  // namespace inertia::config::testing
