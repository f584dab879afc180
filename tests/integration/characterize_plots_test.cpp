// characterize's plots, as a user finds them in the committed output folder: every plot the report
// names is there, and each gnuplot script names its files relative to plots/, so that it draws the
// same picture again when run there (the run wrote into a staging folder of another name).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "tests/support/files.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

using testing::analyze_binary;
using testing::text_of;

int shell(const std::string& command) {
  const int status = std::system(command.c_str());   // NOLINT(cert-env33-c): the test drives the real binaries
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CharacterizePlots, TheReportsPlotsAreDrawnAndTheirScriptsRunAgainInPlace) {
  if (shell("command -v gnuplot >/dev/null 2>&1") != 0) GTEST_SKIP() << "gnuplot is not installed";
  const testing::TempDir dir("inertia-plots");
  const fs::path data = dir.path / "data", out = dir.path / "char";
  ASSERT_EQ(shell(analyze_binary() + " simulate --bench " + INERTIA_SOURCE_DIR + "/config/sim-shaker.toml --out " + data.string() +
                  " >" + (dir.path / "simulate.txt").string() + " 2>&1"),
            0)
      << text_of(dir.path / "simulate.txt");
  ASSERT_EQ(shell(analyze_binary() + " characterize --dataset " + (data / "acc-a").string() + " --out " + out.string() + " >" +
                  (dir.path / "characterize.txt").string() + " 2>&1"),
            0)
      << text_of(dir.path / "characterize.txt");

  const std::string report = text_of(out / "report.md");
  const fs::path plots = out / "plots";
  for (const char* png : {"verification.png", "residuals.png", "adev.png", "psd.png"}) {
    EXPECT_NE(report.find(std::string("plots/") + png), std::string::npos) << png << " is not in the report";
    EXPECT_GT(fs::exists(plots / png) ? fs::file_size(plots / png) : 0U, 1000U) << png;
  }
  for (const char* script : {"verification.gp", "residuals.gp", "noise.gp"}) {
    const std::string text = text_of(plots / script);
    EXPECT_EQ(text.find(".incomplete-"), std::string::npos) << script << " names the staging folder:\n" << text;
    EXPECT_EQ(text.find(dir.path.string()), std::string::npos) << script << " names an absolute path:\n" << text;
  }
  // Drawn again where the user finds them: the same files, from the scripts alone.
  for (const char* png : {"verification.png", "residuals.png", "adev.png", "psd.png"}) fs::remove(plots / png);
  EXPECT_EQ(shell("cd " + plots.string() + " && gnuplot verification.gp residuals.gp noise.gp >/dev/null 2>&1"), 0);
  for (const char* png : {"verification.png", "residuals.png", "adev.png", "psd.png"})
    EXPECT_TRUE(fs::exists(plots / png)) << png << " not drawn again by its script";
}

}  // namespace
}  // namespace inertia
