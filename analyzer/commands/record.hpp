#pragma once
// The lab's record (record/record_store.hpp) from the command line:
//   characterize ... --record DB [--serial SN] [--operator NAME]   (or INERTIA_RECORD=DB): each
//     run appends its characterization;
//   inertia-analyze record list --db DB [--serial SN]
//   inertia-analyze record show --db DB --id N                      (the record and its model)
//   inertia-analyze record history --db DB --serial SN --parameter NAME
//     the parameter across the sensor's characterizations with its expanded uncertainty, each
//     change flagged where En > 1 (ISO 13528's normalized error) against the one before and
//     against the first.
#include <filesystem>
#include <iosfwd>
#include <string>

#include "analyzer/model/model_file.hpp"

namespace inertia::commands {

struct RecordRequest {
  std::filesystem::path db;
  std::string serial;          // empty: the model's sensor name
  std::string operator_name;   // empty: the login name
  std::string bench;
  std::filesystem::path input;        // the dataset folder or log characterized
  std::filesystem::path report_path;
};

/// Appends `model` (with its sheet) to the record; returns its id. Throws InputError for a
/// database refused (damaged, newer schema).
long long record_characterization(const RecordRequest& request, const model::ModelFile& model);

int run_record_list(const std::filesystem::path& db, const std::string& serial, std::ostream& out);
int run_record_show(const std::filesystem::path& db, long long id, std::ostream& out);
int run_record_history(const std::filesystem::path& db, const std::string& serial, const std::string& parameter, std::ostream& out);

}  // namespace inertia::commands
