// libFuzzer target: the bench file and its test-plan includes (common/config), through
// load_bench_config_from_sources, the path INERTIA_BENCH messages take (texts in memory).
// Input: up to four files joined with NULs: the bench file (bench.toml), then the files its
// `include` may name (plan.toml, plan2.toml, plan3.toml). Bad input must be an InputError.
#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace inertia;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const char* const kNames[] = {"bench.toml", "plan.toml", "plan2.toml", "plan3.toml"};
  const auto parts = fuzz::split_at_nul(data, size, 4);
  std::vector<config::SourceFile> sources;
  for (std::size_t i = 0; i < parts.size(); ++i) sources.push_back({kNames[i], std::string(parts[i])});
  try {
    const config::BenchConfig bench = config::load_bench_config_from_sources(sources);
    // A bench that loaded is one the daemon and the analyzer will run on: its numbers are usable.
    if (!(bench.sample_rate_hz > 0.0) || !std::isfinite(bench.t_ref_c)) __builtin_trap();
  } catch (const InputError&) {
  }
  return 0;
}
