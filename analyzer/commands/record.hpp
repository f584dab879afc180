#pragma once
// The lab's record (record/record_store.hpp) from the command line:
//   characterize ... --record DB [--serial SN] [--operator NAME]   (or INERTIA_RECORD=DB): each
//     run appends its characterization;
//   inertia-analyze record list --db DB [--serial SN]
//   inertia-analyze record show --db DB --id N                      (the record and its model)
//   inertia-analyze record history --db DB --serial SN --parameter NAME [--plot FILE.svg]
//     the parameter across the sensor's characterizations with its expanded uncertainty, each
//     change flagged where En > 1 (ISO 13528's normalized error) against the one before and
//     against the first, a drift verdict at a stated false-alarm rate, and the plot;
//   inertia-analyze record compare --db DB --serial SN
//     the sensor's latest parameters against its kind and part's population (percentiles).
//   DB is an SQLite file or a postgresql:// URL.
#include <filesystem>
#include <iosfwd>
#include <string>

#include "analyzer/model/model_file.hpp"
#include "analyzer/record/record_store.hpp"

namespace inertia::commands {

struct RecordRequest {
  std::string operator_name;   // empty: the login name
  std::string bench;
  std::filesystem::path input;        // the dataset folder or log characterized
  std::filesystem::path report_path;
  const report::ParameterSheet* sheet = nullptr;   // the sheet already made of the model; null: made here
};

/// Appends `model` (with its sheet) to `store`; returns its id. The serial is the model's (else
/// its sensor name), the part the model's.
long long record_characterization(record::RecordStore& store, const RecordRequest& request, const model::ModelFile& model);

/// `db`: an SQLite file or a postgresql:// URL.
int run_record_list(const std::string& db, const std::string& serial, std::ostream& out);
int run_record_show(const std::string& db, long long id, std::ostream& out);
/// With `plot`: also draws the history to that SVG file (exit 1 when gnuplot cannot).
int run_record_history(const std::string& db, const std::string& serial, const std::string& parameter, std::ostream& out,
                       const std::filesystem::path& plot = {});
/// The serial's latest characterization against the latest of every other serial of its sensor
/// kind and part: each determined parameter's percentile among them.
int run_record_compare(const std::string& db, const std::string& serial, std::ostream& out);

}  // namespace inertia::commands
