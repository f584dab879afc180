// A triaxial unit on the six-position tumble (config/sim-imu-tumble.toml): simulate, characterize
// each member as the bench's [[unit]] places it, and set the triad (unit/triad_frame.hpp) against
// the simulator's truth (unit-imu1-truth.toml; the members' truth.toml for scale and bias).
//
// Scale factor and bias are each member's own, well determined by the tumble: within 4 sd. The
// non-orthogonality comes from the members' input-axis angles, whose sd each member's
// characterization estimates from the scatter of six poses: few degrees of freedom, so an sd can
// come out far too small (docs/unit.md has the figures over seeds). The bound here is a gross
// check at 6 sd, which a wrong sign or frame breaks by far; the coverage is printed.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>

#include "analyzer/commands/characterize.hpp"
#include "analyzer/compensate/static_response.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/unit/triad_frame.hpp"
#include "common/config/bench_config.hpp"
#include "common/units.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/simulate.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

int seeds_from_environment(int fallback) {
  const char* text = std::getenv("INERTIA_SCENARIO_SEEDS");
  return text != nullptr ? std::max(1, std::atoi(text)) : fallback;
}

TEST(UnitScenario, TumbledTriadMatchesTheSimulatorsTruth) {
  const int runs = seeds_from_environment(2);
  int within_95 = 0, angles = 0;
  for (int run = 0; run < runs; ++run) {
    const testing::TempDir dir("inertia-unit");
    config::BenchConfig bench = config::load_bench_config(fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-imu-tumble.toml");
    config::reseed(bench, 700 + static_cast<std::uint64_t>(run));
    sim::write_simulation(bench, sim::simulate_bench(bench), dir.path / "data");
    std::vector<model::ModelFile> members;
    for (const char* name : {"ax", "ay", "az"}) {
      commands::CharacterizeOptions c;
      c.dataset = dir.path / "data" / name;
      c.out = dir.path / "char" / name;
      c.plots = false;
      std::ostringstream sink;
      ASSERT_EQ(commands::run_characterize(c, sink), 0) << sink.str();
      members.push_back(model::read_model(c.out / "model.toml"));
    }
    const unit::TriadFrame f = unit::triad_frame(members);
    EXPECT_EQ(f.unit, "imu1");
    EXPECT_EQ(f.serial, "IMU-0001");
    for (int k = 0; k < 3; ++k) {
      // The true model (truth.toml in model-file form): its settled sensitivity and bias.
      const model::ModelFile truth = model::read_model(dir.path / "data" / f.axes[static_cast<std::size_t>(k)].sensor / "truth.toml");
      const double scale = compensate::static_sensitivity(truth, ident::Variable::Ai);
      const double bias = compensate::static_output(truth, compensate::InputValues{});
      EXPECT_LT(std::abs(f.scale(k) - scale), 4.0 * f.scale_sd(k)) << k << ": " << f.scale(k) << " truth " << scale;
      EXPECT_LT(std::abs(f.bias(k) - bias), 4.0 * f.bias_sd(k)) << k << ": " << f.bias(k) << " truth " << bias;
    }
    std::ifstream unit_truth_file(dir.path / "data" / "unit-imu1-truth.toml");
    const std::string unit_truth((std::istreambuf_iterator<char>(unit_truth_file)), std::istreambuf_iterator<char>());
    std::string line;
    for (std::size_t p = 0; p < 3; ++p) {
      std::smatch m;
      ASSERT_TRUE(std::regex_search(unit_truth, m, std::regex(std::string("\\n") + unit::kAxisPairs[p] + " = ([-+0-9.eE]+)")));
      const double truth = std::stod(m[1]);
      const double z = (f.non_orthogonality[p] - truth) / f.non_orthogonality_sd[p];
      EXPECT_LT(std::abs(z), 6.0) << unit::kAxisPairs[p] << ": estimate " << f.non_orthogonality[p] << " truth " << truth;
      within_95 += std::abs(z) < 1.96;
      ++angles;
      line += fmt::format(" {} {:+.2f} mrad (truth {:+.2f}, z {:+.2f})", unit::kAxisPairs[p], 1e3 * f.non_orthogonality[p], 1e3 * truth, z);
    }
    std::cout << "[ figures ] seed " << 700 + run << ":" << line << "\n";
  }
  std::cout << "[ figures ] non-orthogonality within its 95 % interval: " << within_95 << " of " << angles << "\n";
}

}  // namespace
}  // namespace inertia
