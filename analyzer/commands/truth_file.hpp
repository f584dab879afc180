#pragma once
// truth.toml, written by `inertia-analyze simulate` beside a simulated dataset: the true model
// terms (model-file form) and the true M_E^S of every case, so an identification can be scored.
#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "common/frames.hpp"

namespace inertia::commands {

struct Truth {
  std::map<std::string, double> terms;            // canonical term -> coefficient (output unit per SI)
  std::map<std::string, frames::Dcm> m_es;        // case name -> true M_E^S
  std::map<std::string, double> params;           // [params] of the sensor (paper units)
  frames::Dcm m_cs = frames::Dcm::Identity();
};

/// Reads DIR/truth.toml when present; nullopt when the dataset has none. Throws InputError when the
/// file exists but is malformed.
std::optional<Truth> read_truth(const std::filesystem::path& dataset_dir);

}  // namespace inertia::commands
