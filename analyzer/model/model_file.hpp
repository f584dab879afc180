#pragma once
// The model file (docs/design.md, "Model file"): written by characterize, read by diagnose and
// simulate.
//
//   sensor = "accelerometer"                  # or "gyroscope"
//   m_cs = [[...], [...], [...]]              # M_C^S, sensor misalignment relative to the case
//   [terms]                                   # term -> coefficient, output unit per SI input unit
//   "1" = 3.44e-3
//   "a_i" = 0.0877
//   [std]                                     # optional: term -> standard deviation of the coefficient
//   "a_i" = 2.1e-6
//   [noise]                                   # optional
//   white_sd = 1.0e-4                         # the innovation's sd (after the AR noise model)
//   output_sd = 2.0e-4                        # optional: the output's sd about the model's free
//                                             #   run on the characterization's records, every
//                                             #   noise colour in (compensation's noise)
//   N = 1.0e-6                                # optional noise terms of IEEE 952 Annex C (inertia-analyze
//   B = 2.0e-5                                #   noise): Q quantization (unit s), N white (unit s^1/2),
//   K = 3.0e-7                                #   B bias instability (unit), K rate random walk
//                                             #   (unit s^-1/2), R rate ramp (unit s^-1)
//   [noise.std]                               # optional: each noise term's standard deviation
//   B = 1.1e-6                                #   (its 95 % interval's half-width / 1.96)
//
// Optional keys that let the model be applied to other data (compensate, export), written by
// characterize:
//   sensor_name = "acc1"                      # the sensor's name (bench file, dataset.toml)
//   serial = "SN-0042"                        # the unit's serial number, and its part (type)
//   part = "QA-2000"
//   unit = "imu1"                             # the [[unit]] it belongs to, and its axis there
//   unit_axis = "y"
//   output_unit = "mA"                        # the output's unit
//   t_ref = 25.0                              # degC: the model's T is temp - t_ref
//   sample_period_s = 1.0e-3                  # the period the lags [k-j] count in
//   [covariance]                              # the coefficients' covariance
//   terms = ["1", "a_i"]                      #   its rows and columns, each a term of [terms] once
//   matrix = [[4.0e-12, 1.0e-14], [1.0e-14, 4.4e-12]]
//   [range]                                   # each input's span over the characterization's
//   a_i = [-9.81, 9.81]                       #   samples: variable = [lowest, highest]
//   [misalignment]                            # the input axis from the nominal case frame (the
//   about_p = 1.4e-3                          #   first mounting), rad, each with its sd:
//   about_o = -1.4e-3                         #   the axis turns about p towards -o and about o
//   sd_p = 2.0e-5                             #   towards +p (frames::frame_rotation's sense)
//   sd_o = 2.0e-5
//   [undetermined]                            # terms the plan did not determine, and why
//   "a_i^2" = "no case excites a_i beyond 1 g"
//   [conditions]                              # what the characterization saw
//   duration_s = 109.0
//   source = "acc1"                           #   dataset folder or log
//   cases = ["multipoint", "rate-series"]
//   software = "inertia 0.1.0 (37c9ae5)"
//   date = "2026-11-29T13:40:00Z"
//   [[case_frame]]                            # each characterized case's estimated M_E^S (the
//   case = "shaker-ia"                        #   sensor in the bench's external frame, fixture
//   m_es = [[...], [...], [...]]              #   included), for records of the same bench
//
// Meaning of the coefficients: y (1 + sum_b c_b p_b) = sum_a c_a term_a, where the output-multiplied
// terms y*p_b (rational models, paper eq. 5: y*T, y*w_i) carry their denominator coefficient c_b
// and every other term its ordinary coefficient. Without output-multiplied terms this is simply
// y = sum c_j term_j. Estimation (ULS), simulation and the simulator's truth use this convention.
// Term keys are written in canonical form (analyzer/ident/term.hpp) and read in any spelling the
// grammar accepts. Other top-level keys are ignored, so later versions can add information.
#include <algorithm>
#include <array>
#include <Eigen/Dense>
#include <filesystem>
#include <map>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::model {

struct ModelTerm {
  ident::Term term;
  double coefficient = 0.0;
  std::optional<double> std;   // standard deviation of the coefficient, when known
};

struct ModelFile {
  dataset::SensorKind sensor = dataset::SensorKind::Accelerometer;
  frames::Dcm m_cs = frames::Dcm::Identity();
  std::vector<ModelTerm> terms;     // in file order
  std::optional<double> white_sd;   // [noise] white_sd, output unit
  std::optional<double> output_sd;  // [noise] output_sd, output unit
  /// [noise] Q, N, B, K, R (IEEE 952 Annex C, the units above), when a noise analysis gave them:
  /// slot i is noise::NoiseTerm(i), written under kKeys[i]. The one list of the slots.
  struct NoiseTerms {
    static constexpr std::array<const char*, 5> kKeys{"Q", "N", "B", "K", "R"};
    std::array<std::optional<double>, kKeys.size()> values;
    /// [noise.std] (optional): each term's standard deviation, from its fit's 95 % interval.
    std::array<std::optional<double>, kKeys.size()> sd;
    [[nodiscard]] bool any() const {
      return std::any_of(values.begin(), values.end(), [](const std::optional<double>& v) { return v.has_value(); });
    }
  } noise;
  /// square_highpass_rad_s (top level, optional): the squares a_i^2, a_p^2, a_o^2 pass eq. 12's
  /// first-order high pass s / (s + b) with this corner; absent: they act statically.
  std::optional<double> square_highpass_rad_s;

  std::string name;                        // sensor_name; empty: not stated
  std::string serial, part;                // serial, part; empty: not stated
  std::string unit;                        // unit; empty: not a unit's member
  int unit_axis = -1;                      // unit_axis: 0, 1, 2 for "x", "y", "z"; -1 without unit
  std::string output_unit;                 // output_unit; empty: not stated
  std::optional<double> t_ref;             // t_ref, degC
  std::optional<double> sample_period_s;   // sample_period_s
  /// [covariance], rows and columns in the order of `terms` (whatever the file's order); 0 x 0
  /// when the file has none.
  Eigen::MatrixXd covariance;
  /// [range]: the characterized span of each input variable the file states.
  struct Span {
    double lowest = 0.0, highest = 0.0;
  };
  std::map<ident::Variable, Span> range;
  /// [[case_frame]], in file order.
  struct CaseFrame {
    std::string case_name;
    frames::Dcm m_es = frames::Dcm::Identity();
  };
  std::vector<CaseFrame> case_frames;
  /// [misalignment]: angles about p and o of the first mounting, and their sd (rad).
  struct Misalignment {
    double about_p = 0.0, about_o = 0.0, sd_p = 0.0, sd_o = 0.0;
    /// dof: the degrees of freedom of sd_p and sd_o (the tilts' between the mounting's phases on a
    /// tumble); infinite (absent in the file) when many.
    double dof = std::numeric_limits<double>::infinity();
  };
  std::optional<Misalignment> misalignment;
  /// [undetermined], term text -> reason, in file order.
  std::vector<std::pair<std::string, std::string>> undetermined;
  /// [conditions]
  struct Conditions {
    std::optional<double> duration_s;
    std::string source, software, date;
    std::vector<std::string> cases;
  };
  Conditions conditions;

  /// The coefficient of `term`, or nullopt when the model does not hold it.
  [[nodiscard]] std::optional<double> coefficient(const ident::Term& term) const;
};

/// Reads and validates a model file. Throws InputError naming file, line and column for a TOML
/// syntax error, a missing or mistyped key, an m_cs that is not a rotation (tolerance
/// dataset::kRotationTolerance), a term the grammar rejects (the message holds the grammar's
/// reason), a term given twice in two spellings, a non-finite coefficient, a [std] entry for a
/// term that [terms] lacks, a [covariance] whose terms are not those of [terms] or whose matrix is
/// not square, symmetric (to 1e-9 of its diagonal's scale) with a non-negative diagonal, or a
/// [range] entry that is not a known input variable with lowest <= highest, or a [[case_frame]]
/// without a case name, with a name given twice, or with an m_es that is not a rotation.
ModelFile read_model(const std::filesystem::path& file);

/// The same from text; `source_name` is used in error messages.
ModelFile parse_model(std::string_view text, const std::string& source_name);

/// The file's text: canonical term names, numbers in shortest round-trip form (so read(write(m))
/// == m bit for bit), terms in the order given. Throws InputError for a non-finite number.
std::string format_model(const ModelFile& model);

/// Writes format_model(model) to `file` whole or not at all: into a temporary file beside it,
/// flushed to the disk, then renamed over it, so a reader (or a run killed part way) sees the
/// old file or the new one, never a part. Throws std::system_error on I/O failure.
void write_model(const std::filesystem::path& file, const ModelFile& model);

}  // namespace inertia::model
