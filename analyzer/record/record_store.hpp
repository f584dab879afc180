#pragma once
// The lab's record: every characterization kept, with what it was made from, in an embedded
// SQLite file (created on first use) or on a PostgreSQL server that several bench PCs share
// (record_database.hpp). Append-only: a re-run is a new row, and the database refuses UPDATE and
// DELETE (triggers). Each record is one transaction, so a run killed while writing leaves the
// database as it was before it. Several writers may share one record.
//
// Schema (version kSchemaVersion; a newer one is refused, an older one migrated):
//   characterization(id, recorded_utc, serial, sensor_name, sensor_kind, bench, operator, plan,
//                    software, input_path, input_sha256, model_toml, sheet_json, report_path, part, unit)
//   parameter(characterization_id, name, unit, status, value, expanded_uncertainty)
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/record/record_database.hpp"
#include "analyzer/report/parameter_sheet.hpp"

namespace inertia::record {

struct Characterization {
  long long id = 0;             // set by the store
  std::string recorded_utc;     // set by the store
  std::string serial, sensor_name, sensor_kind, bench, operator_name, plan, software;
  std::string part;             // the sensor's type (part number): its population for compare
  std::string unit;             // the triaxial unit it belongs to ([[unit]]); empty: none
  std::string input_path, input_sha256;
  std::string model_toml, sheet_json, report_path;
  std::vector<report::SheetEntry> parameters;   // the sheet's entries (determined ones carry values)
};

struct ParameterPoint {
  long long id = 0;
  std::string recorded_utc;
  std::string status;
  std::optional<double> value, expanded_uncertainty;
  std::string unit;
};

/// A determined parameter of one characterization, for setting a sensor against its population.
struct PopulationValue {
  long long id = 0;
  std::string serial, name, unit;
  double value = 0.0, expanded_uncertainty = 0.0;
};

class RecordStore {
 public:
  /// Opens (creating on first use) the record at `location`: a postgresql:// URL, or else an
  /// SQLite file. Throws InputError, writing nothing, for a damaged file or one that is not a
  /// database, a server it cannot reach, and a record of a newer schema.
  explicit RecordStore(const std::string& location);

  /// Appends one characterization and its parameters in one transaction; returns its id.
  long long add(Characterization c);

  [[nodiscard]] std::vector<Characterization> list(const std::string& serial = {}) const;   // without the long texts
  [[nodiscard]] std::optional<Characterization> show(long long id) const;
  /// One parameter across a sensor's characterizations, oldest first.
  [[nodiscard]] std::vector<ParameterPoint> history(const std::string& serial, const std::string& parameter) const;
  /// The determined parameters of the latest characterization of every serial of one sensor kind
  /// and part (the population a unit of that type is compared with), in id order.
  [[nodiscard]] std::vector<PopulationValue> population(const std::string& sensor_kind, const std::string& part) const;
  [[nodiscard]] std::string describe() const { return database_->describe(); }

 private:
  std::unique_ptr<RecordDatabase> database_;
};

/// SHA-256 (hex) of a record's input: a file's bytes, or a dataset folder's dataset.toml and case
/// files (each name and content, in name order).
std::string input_sha256(const std::filesystem::path& input);

/// A drift across a history: the first characterization whose value differs from the first one's
/// by more than chance explains at the family-wise level `family_alpha` over the history's m
/// comparisons with the first (Bonferroni): En > z(1 - alpha / 2m) / 2, z the normal quantile,
/// since En = |z-score| / 2 for expanded uncertainties U = 2u. Per-comparison En > 1 is the 95 %
/// interval exceeded once; over a history of several calibrations it would flag a stable sensor
/// far more often than 5 %. Returns the index into `points` (nullopt: none), and the threshold.
struct Drift {
  std::optional<std::size_t> first_flagged;
  double en_threshold = 0.0;
};
Drift find_drift(const std::vector<ParameterPoint>& points, double family_alpha = 0.05);

/// En, the normalized error of two results with expanded uncertainties (ISO 13528):
/// |a - b| / sqrt(Ua^2 + Ub^2); a change with En > 1 is larger than the two can explain.
double normalized_error(double a, double ua, double b, double ub);

/// Where `value` stands among `others` (the population without the unit itself): the percentage of
/// them below it, a tie counted as half below (the mid-rank percentile), so that a unit at the
/// population's median stands at 50. NaN for an empty population.
double percentile_rank(double value, const std::vector<double>& others);

}  // namespace inertia::record
