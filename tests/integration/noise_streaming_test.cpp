// `inertia-analyze noise --dataset` streams its case files (dataset::CaseRowStream): its peak
// memory does not grow with the record. The same static record at two lengths, 6x apart, run as
// the real binary; the peak resident set of each from the kernel (wait4's ru_maxrss).
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <filesystem>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "common/dataset/dataset.hpp"
#include "tests/support/child_process.hpp"
#include "tests/support/files.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

/// A dataset of one static case of `rows` rows at 10 kHz: white noise on a bias.
void write_rest_record(const fs::path& dir, Eigen::Index rows) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  dataset::Dataset d;
  d.output_unit = "mA";
  dataset::CaseData c;
  c.name = "rest";
  c.kind = CaseKind::Static;
  c.file = "rest.csv";
  c.t = Eigen::VectorXd::LinSpaced(rows, 0.0, static_cast<double>(rows - 1) * 1e-4);
  c.a_e = dataset::Matrix3Columns::Zero(rows, 3);
  c.a_e.col(2).setConstant(9.80665);
  c.y.resize(rows);
  for (double& v : c.y) v = 4.0 + noise(rng);
  d.cases.push_back(std::move(c));
  dataset::write_dataset(dir, d);
}

/// Runs `args`, output to `log`; returns (exit status, peak resident set in kB).
std::pair<int, long> run_measured(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = testing::start_child(args, log);
  int status = 0;
  struct rusage usage {};
  ::wait4(pid, &status, 0, &usage);
  return {status, usage.ru_maxrss};
}

TEST(NoiseStreaming, PeakMemoryDoesNotGrowWithTheRecord) {
  const testing::TempDir dir("inertia-noise-streaming");
  std::vector<long> peak_kb;
  // Both beyond the fixed sizes: a group of blocks (one a thread, 4 MB of text each) and Welch's
  // longest segment (2^16 samples, reached at 2^18 rows of rest).
  for (const Eigen::Index rows : {Eigen::Index{400'000}, Eigen::Index{2'400'000}}) {
    const fs::path data = dir.path / ("rows-" + std::to_string(rows));
    write_rest_record(data, rows);
    const auto [status, kb] = run_measured({testing::analyze_binary(), "noise", "--dataset", data.string(), "--out",
                                            (data / "noise").string()},
                                           dir.path / "noise.txt");
    ASSERT_EQ(status, 0) << testing::text_of(dir.path / "noise.txt");
    peak_kb.push_back(kb);
    std::cout << "[ figures ] noise --dataset of " << rows << " rows: peak RSS " << kb / 1024 << " MB\n";
  }
  // Held whole, the 2,000,000 more rows would add 80 MB of columns (t, a, y: 40 B a row) and
  // about 120 MB of text. Streamed, the Allan accumulator's levels grow by 32 kB an octave; less
  // than one block of text (4 MB) is allowed for the rest.
  EXPECT_LT(peak_kb[1] - peak_kb[0], 4 * 1024) << peak_kb[0] << " kB then " << peak_kb[1] << " kB";
}

}  // namespace
}  // namespace inertia
