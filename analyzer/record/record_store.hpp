#pragma once
// The lab's record: every characterization kept, with what it was made from, in an embedded
// SQLite database (one file, created on first use). Append-only: a re-run is a new row, and the
// database refuses UPDATE and DELETE (triggers). Each record is one transaction, so a run killed
// while writing leaves the database as it was before it. Several writers may share the file
// (SQLite's write-ahead log; a writer waits up to 30 s for another's transaction).
//
// Schema (PRAGMA user_version = kSchemaVersion; a newer file is refused, an older one migrated):
//   characterization(id, recorded_utc, serial, sensor_name, sensor_kind, bench, operator, plan,
//                    software, input_path, input_sha256, model_toml, sheet_json, report_path)
//   parameter(characterization_id, name, unit, status, value, expanded_uncertainty)
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/report/parameter_sheet.hpp"

struct sqlite3;

namespace inertia::record {

inline constexpr int kSchemaVersion = 1;

struct Characterization {
  long long id = 0;             // set by the store
  std::string recorded_utc;     // set by the store
  std::string serial, sensor_name, sensor_kind, bench, operator_name, plan, software;
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

class RecordStore {
 public:
  /// Opens (creating on first use) the database at `file`. Throws InputError, writing nothing, for
  /// a file that is not an SQLite database or is damaged, and for one of a newer schema.
  explicit RecordStore(const std::filesystem::path& file);
  ~RecordStore();
  RecordStore(const RecordStore&) = delete;
  RecordStore& operator=(const RecordStore&) = delete;

  /// Appends one characterization and its parameters in one transaction; returns its id.
  long long add(Characterization c);

  [[nodiscard]] std::vector<Characterization> list(const std::string& serial = {}) const;   // without the long texts
  [[nodiscard]] std::optional<Characterization> show(long long id) const;
  /// One parameter across a sensor's characterizations, oldest first.
  [[nodiscard]] std::vector<ParameterPoint> history(const std::string& serial, const std::string& parameter) const;

 private:
  void execute(const char* sql) const;
  std::filesystem::path file_;
  sqlite3* db_ = nullptr;
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

}  // namespace inertia::record
