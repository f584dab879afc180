#include "analyzer/commands/unit.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <cmath>
#include <ostream>

#include "analyzer/model/model_file.hpp"
#include "analyzer/unit/triad_frame.hpp"
#include "common/atomic_file.hpp"
#include "common/input_error.hpp"
#include "common/output_folder.hpp"
#include "common/toml_text.hpp"

namespace inertia::commands {

namespace {

std::string row_text(const Eigen::Vector3d& v) { return fmt::format("[{}, {}, {}]", toml_float(v(0)), toml_float(v(1)), toml_float(v(2))); }

std::string unit_toml(const unit::TriadFrame& f) {
  const bool gyro = f.kind == dataset::SensorKind::Gyroscope;
  std::string s = "# The triad of a unit in its housing's frame (inertia-analyze unit). Sensitivities in the members' output unit\n"
                  "# per input unit (m/s^2 or rad/s); input = R^-1 K^-1 (y - b) (imucal's convention); sd: standard uncertainties.\n";
  s += "unit = " + toml_quote(f.unit) + "\n";
  if (!f.serial.empty()) s += "serial = " + toml_quote(f.serial) + "\n";
  s += fmt::format("kind = \"{}\"\n", dataset::to_string(f.kind));
  if (!f.output_unit.empty()) s += "output_unit = " + toml_quote(f.output_unit) + "\n";
  s += fmt::format("input_unit = \"{}\"\n", gyro ? "rad/s" : "m/s^2");
  s += fmt::format("members = [{}, {}, {}]\n", toml_quote(f.axes[0].sensor), toml_quote(f.axes[1].sensor), toml_quote(f.axes[2].sensor));
  s += "\n[imucal]\n";
  s += fmt::format("K = {}            # the diagonal of K: |s_k|\nK_sd = {}\n", row_text(f.scale), row_text(f.scale_sd));
  s += fmt::format("R = [{}, {}, {}]   # rows: the sensitive axes\n", row_text(f.misalignment.row(0)), row_text(f.misalignment.row(1)),
                   row_text(f.misalignment.row(2)));
  s += fmt::format("b = {}\nb_sd = {}\n", row_text(f.bias), row_text(f.bias_sd));
  s += "\n[non_orthogonality]   # asin(n_j . n_k), rad: how much closer than 90 deg\n";
  for (std::size_t p = 0; p < 3; ++p)
    s += fmt::format("{0} = {1}\n{0}_sd = {2}\n", unit::kAxisPairs[p], toml_float(f.non_orthogonality[p]), toml_float(f.non_orthogonality_sd[p]));
  for (std::size_t k = 0; k < 3; ++k) {
    const unit::TriadAxis& a = f.axes[k];
    s += fmt::format("\n[axis.{}]\nsensor = {}\nsensitivity = {}\ncovariance = [{}, {}, {}]\nangles_estimated = {}\n",
                     static_cast<char>('x' + k), toml_quote(a.sensor), row_text(a.sensitivity), row_text(a.covariance.row(0)),
                     row_text(a.covariance.row(1)), row_text(a.covariance.row(2)), a.angles_estimated ? "true" : "false");
  }
  return s;
}

}  // namespace

int run_unit(const std::vector<std::filesystem::path>& models, const std::filesystem::path& out, std::ostream& summary) {
  OutputFolder folder(out, "unit");
  std::vector<model::ModelFile> members;
  for (const std::filesystem::path& m : models) members.push_back(model::read_model(m));
  const unit::TriadFrame f = unit::triad_frame(members);
  const bool gyro = f.kind == dataset::SensorKind::Gyroscope;
  fmt::print(summary, "unit {}{}: {} triad {}, {}, {} (along x, y, z)\n", f.unit, f.serial.empty() ? "" : " (serial " + f.serial + ")",
             dataset::to_string(f.kind), f.axes[0].sensor, f.axes[1].sensor, f.axes[2].sensor);
  fmt::print(summary, "  {:<4} {:>14} {:>10}  {:<44} {:>14} {:>10}\n", "axis", fmt::format("K ({}/{})", f.output_unit, gyro ? "rad/s" : "m/s2"),
             "sd", "sensitive axis n in the unit frame", fmt::format("b ({})", f.output_unit), "sd");
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d n = f.misalignment.row(k).transpose();
    fmt::print(summary, "  {:<4} {:>14.8g} {:>10.2g}  [{:+.7f} {:+.7f} {:+.7f}]   {:>14.6g} {:>10.2g}\n", static_cast<char>('x' + k),
               f.scale(k), f.scale_sd(k), n(0), n(1), n(2), f.bias(k), f.bias_sd(k));
  }
  fmt::print(summary, "non-orthogonality (asin of n_j . n_k: how much closer than 90 deg), mrad:");
  for (std::size_t p = 0; p < 3; ++p)
    fmt::print(summary, " {} {:+.4f} +- {:.4f}", unit::kAxisPairs[p], 1e3 * f.non_orthogonality[p], 1e3 * f.non_orthogonality_sd[p]);
  fmt::print(summary, " (sd)\n");
  for (const unit::TriadAxis& a : f.axes) {
    if (!a.angles_estimated)
      fmt::print(summary, "note: {}'s input-axis angles were held, not estimated (its model has no [misalignment] sd): its axis "
                          "carries only the coefficients' uncertainty\n",
                 a.sensor);
  }
  write_file_atomically(folder.path() / "unit.toml", unit_toml(f));
  folder.commit();
  fmt::print(summary, "wrote {}\n", (folder.target() / "unit.toml").string());
  return kExitOk;
}

}  // namespace inertia::commands
