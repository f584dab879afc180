#pragma once
// The dataset folder contract (design.md, "Dataset folder"): dataset.toml plus one CSV per case.
// Everything in memory is SI: a_e in m/s^2, w_e in rad/s, temp in degC, t in s.
#include <Eigen/Dense>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/frames.hpp"

namespace inertia::dataset {

enum class SensorKind { Accelerometer, Gyroscope };
enum class CaseKind { RotationTable, Shaker, Thermal, Static };

using Matrix3Columns = Eigen::Matrix<double, Eigen::Dynamic, 3>;

/// One test case: one mounting of the sensor, one CSV file.
struct CaseData {
  std::string name;
  CaseKind kind = CaseKind::Static;
  std::string file;                                   // CSV file name, relative to the dataset folder
  frames::Dcm m_ec = frames::Dcm::Identity();         // nominal M_E^C (rows: IRA, XRA, YRA in F_E)
  double sample_period_s = 0.0;                       // from the uniform `t` column
  Eigen::VectorXd t;                                  // s
  Matrix3Columns a_e;                                 // reference specific force in F_E, m/s^2
  std::optional<Matrix3Columns> w_e;                  // reference rate in F_E, rad/s
  std::optional<Eigen::VectorXd> temp;                // degC
  Eigen::VectorXd y;                                  // sensor output, in the dataset's output unit
  std::vector<std::string> phase_names;               // distinct labels, in order of first appearance
  std::vector<std::uint16_t> phase;                   // per sample index into phase_names; empty if no column

  [[nodiscard]] Eigen::Index size() const { return t.size(); }
};

struct Dataset {
  SensorKind sensor = SensorKind::Accelerometer;
  std::string output_unit;
  double t_ref = 25.0;                                // degC; model variable T = temp - t_ref
  std::vector<CaseData> cases;
};

/// Reads dataset.toml and every case CSV in `dir`. Throws InputError naming file, line and column
/// for a missing required column, a non-number, a NaN, a non-uniform time column or a bad
/// dataset.toml. Unknown columns are ignored with a warning on stderr.
Dataset read_dataset(const std::filesystem::path& dir);

/// Writes dataset.toml and one CSV per case into `dir` (created if needed), full double precision.
void write_dataset(const std::filesystem::path& dir, const Dataset& data);

const char* to_string(SensorKind kind);
const char* to_string(CaseKind kind);

}  // namespace inertia::dataset
