#pragma once
// Small helpers for the simulator tests: a bench file written to a fresh temporary folder.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/config/bench_config.hpp"

namespace inertia::sim::test {

inline std::filesystem::path temp_dir(const std::string& tag) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("inertia_sim_test_" + std::string(info->test_suite_name()) + "_" +
                                     info->name() + "_" + tag);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::filesystem::path write_file(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p) << text;
  return p;
}

inline config::BenchConfig bench_from(const std::string& text) {
  return config::load_bench_config(write_file(temp_dir("cfg") / "bench.toml", text));
}

}  // namespace inertia::sim::test
