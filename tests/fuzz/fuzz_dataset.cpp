// libFuzzer target: the dataset folder (docs/design.md "Dataset folder"), common/dataset.
// Input: dataset.toml, NUL, the CSV of its case(s) (named case.csv in the seeds). The CSV alone
// also goes through read_case_csv, so CSV mutations are explored whatever the TOML became.
// Bad input must be an InputError; anything else (a crash, another exception, a sanitizer
// report) is a bug.
#include <sstream>

#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace inertia;

namespace {
void check_case(const dataset::CaseData& c) {
  // What read_case_csv promises of a case it accepted.
  const Eigen::Index n = c.t.size();
  if (n < 1 || c.a_e.rows() != n || c.y.size() != n) __builtin_trap();
  if (c.w_e && c.w_e->rows() != n) __builtin_trap();
  if (c.temp && c.temp->size() != n) __builtin_trap();
  if (!c.phase.empty() && static_cast<Eigen::Index>(c.phase.size()) != n) __builtin_trap();
  for (std::uint16_t p : c.phase)
    if (p >= c.phase_names.size()) __builtin_trap();
  if (!c.t.allFinite() || !c.a_e.allFinite() || !c.y.allFinite()) __builtin_trap();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fuzz::ScratchCleanup cleanup;
  const auto parts = fuzz::split_at_nul(data, size, 2);
  const std::filesystem::path dir = fuzz::scratch_dir() / "dataset";
  std::filesystem::create_directories(dir);
  const std::string_view csv = parts.size() > 1 ? parts[1] : parts[0];
  fuzz::write_file(dir / "case.csv", csv);
  std::ostringstream warnings;
  try {
    dataset::CaseData c;
    dataset::read_case_csv(dir / "case.csv", c, warnings);
    check_case(c);
  } catch (const InputError&) {
  }
  if (parts.size() > 1) {
    fuzz::write_file(dir / "dataset.toml", parts[0]);
    try {
      const dataset::Dataset d = dataset::read_dataset(dir, warnings);
      for (const dataset::CaseData& c : d.cases) check_case(c);
    } catch (const InputError&) {
    }
  }
  return 0;
}
