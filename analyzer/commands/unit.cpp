#include "analyzer/commands/unit.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <optional>
#include <ostream>

#include "analyzer/model/model_file.hpp"
#include "analyzer/unit/kalibr_intrinsics.hpp"
#include "analyzer/unit/triad_frame.hpp"
#include "analyzer/unit/unit_covariance.hpp"
#include "analyzer/unit/unit_files.hpp"
#include "analyzer/unit/unit_model.hpp"
#include "common/atomic_file.hpp"
#include "common/input_error.hpp"
#include "common/output_folder.hpp"
#include "common/toml_text.hpp"

namespace inertia::commands {

namespace {

void print_triad(const unit::TriadFrame& f, std::ostream& summary) {
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
  fmt::print(summary, "  non-orthogonality (asin of n_j . n_k: how much closer than 90 deg), mrad, with its sd and 95 % interval:\n");
  for (std::size_t p = 0; p < 3; ++p) {
    const double dof = f.non_orthogonality_dof[p];
    fmt::print(summary, "    {} {:+.4f} +- {:.4f} ({}): [{:+.4f}, {:+.4f}]\n", unit::kAxisPairs[p], 1e3 * f.non_orthogonality[p],
               1e3 * f.non_orthogonality_sd[p], std::isfinite(dof) ? fmt::format("Student's t on {:.1f} dof", dof) : std::string("normal"),
               1e3 * (f.non_orthogonality[p] - f.non_orthogonality_half_width[p]),
               1e3 * (f.non_orthogonality[p] + f.non_orthogonality_half_width[p]));
  }
  if (gyro)
    fmt::print(summary, "  note: a gyroscope's axis comes from the rate sensitivities of its cases: its sd, and the "
                        "non-orthogonality's, carry how well the fixture placed each case only as the dataset states it "
                        "(placement_sd_deg; a case without it counts as placed exactly; docs/unit.md)\n");
  for (const unit::TriadAxis& a : f.axes) {
    if (!a.angles_estimated)
      fmt::print(summary, "  note: {}'s input-axis angles were held, not estimated (its model has no [misalignment] sd): its axis "
                          "carries only the coefficients' uncertainty\n",
                 a.sensor);
  }
}

}  // namespace

int run_unit(const std::vector<std::filesystem::path>& models, const std::filesystem::path& out, std::ostream& summary) {
  if (models.size() != 3 && models.size() != 6)
    throw InputError(fmt::format("unit: three models of one triad, or six (accelerometers and gyroscopes): {} given", models.size()));
  OutputFolder folder(out, "unit");
  std::vector<model::ModelFile> members;
  for (const std::filesystem::path& m : models) {
    members.push_back(model::read_model(m));
    // The member's model as characterized, beside unit.toml: the folder is the whole unit.
    write_file_atomically(folder.path() / unit::member_file_name(members.back().name), model::format_model(members.back()));
  }
  const unit::Triads triads = unit::triads_of(members);
  for (const auto& triad : {triads.accelerometer, triads.gyroscope}) {
    if (triad) print_triad(*triad, summary);
  }
  const std::vector<unit::UnitParameter> parameters = unit::unit_parameters(triads);
  write_file_atomically(folder.path() / "unit.toml", unit::unit_toml(triads, parameters));
  write_file_atomically(folder.path() / "imucal.json", unit::imucal_json(triads).dump(4) + "\n");
  const unit::KalibrIntrinsics kalibr = unit::kalibr_intrinsics(triads.accelerometer, triads.gyroscope);
  if (!kalibr.note.empty()) fmt::print(summary, "note: Kalibr's intrinsics left out: {}\n", kalibr.note);
  write_file_atomically(folder.path() / "kalibr.yaml", unit::kalibr_yaml(triads, parameters));
  folder.commit();
  fmt::print(summary, "wrote {}: unit.toml, the members' model files, imucal.json and kalibr.yaml\n", folder.target().string());
  return kExitOk;
}

}  // namespace inertia::commands
