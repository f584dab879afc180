#pragma once
// `inertia-analyze compensate --model M.toml --dataset DIR|--log FILE [--sensor S] --out FILE.csv`:
// each sample's sensed input (a_i in m/s^2, w_i in rad/s) from the sensor's raw output, by the
// model read backwards (compensate/inverse_model.hpp), with its standard uncertainty.
//
// The other inputs the model reads come from the record's references in the sensor frame: for a
// case the model was characterized on (its [[case_frame]], by name), in the M_E^S estimated then,
// since a record of the same bench has the same fixtures; otherwise, or with --case-frames
// nominal, M_E^S = M_C^S (the model's) M_E^C (the case's nominal). With --other-axes zero, the other
// two axes of the sensed quantity are 0 (temperature and, for a gyro, specific force still come
// from the references). The CSV has one row per compensated sample:
//   case, t, y, a_i (or w_i), u, u_coefficients, u_noise, flag, a_i_reference
// u is the root sum of squares of the two parts; flag is ok, outside_range or not_converged; the
// reference is the record's own input along the sensed axis, for comparison.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/unit/unit_model.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::commands {

struct CompensateOptions {
  std::filesystem::path model;
  std::filesystem::path dataset;
  std::filesystem::path event_log;
  std::string sensor;              // with --log
  std::filesystem::path out;       // the CSV
  bool other_axes_zero = false;
  bool case_frames_from_model = true;
  double range_margin = 0.01;
};

/// What the compensation of case `case_index` of `data` reads: y, the known inputs (in the
/// characterized M_E^S where the model has the case's frame and `frames_from_model`, else in the
/// nominal one; the other axes zeroed with `other_axes_zero`), and the sensed input itself as the
/// reference to compare with.
struct CompensationRecord {
  ident::SignalSet signals;
  bool characterized_frame = false;
};
CompensationRecord compensation_record(const model::ModelFile& model, const compensate::InverseModel& inverse,
                                       const dataset::Dataset& data, std::size_t case_index, bool frames_from_model,
                                       bool other_axes_zero);

/// One record per member of `unit`, in its order: the members' dataset folders under
/// `dataset_dir` (one per member, by name), or each member's sensor in `event_log` when that is
/// given. InputError for a member without its record, a record of another sensor, serial or sample
/// period than its model's, or members' records of different cases.
std::vector<dataset::Dataset> unit_records(const unit::UnitModel& unit, const std::filesystem::path& dataset_dir,
                                           const std::filesystem::path& event_log);

/// InputError for a model of another sensor kind or name than the record's, a record at another
/// sample period than the model's lags count in, a model that cannot be inverted, or a record
/// without an input the model reads.
int run_compensate(const CompensateOptions& options, std::ostream& out);

}  // namespace inertia::commands
