#pragma once
// `inertia-analyze reproduce-paper [--json OUT.json]`: the paper's section 3 experiment simulated
// over several seeds, its test cases (1), (2) and (3), and a case (4) the paper proposed and did not
// run (model selection with dynamics and coloured noise); tables 2, 3 and 4 printed beside the
// paper's numbers. Lives beside main.cpp, not in inertia_analyzer: it is where the simulator and
// the analysis meet (docs/design.md: analyzer -> common only).
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <vector>

namespace inertia::commands {

struct ReproducePaperOptions {
  std::filesystem::path bench;               // the paper's bench (config/sim-paper.toml)
  std::vector<std::uint64_t> seeds;          // one simulation per seed
  std::filesystem::path json;                // empty: no JSON
  int order = 2;                             // r of case (4)
};

int run_reproduce_paper(const ReproducePaperOptions& options, std::ostream& out);

}  // namespace inertia::commands
