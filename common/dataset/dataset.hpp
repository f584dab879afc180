#pragma once
// The dataset folder contract (docs/design.md, "Dataset folder"): dataset.toml plus one CSV per case.
// Everything in memory is SI: a_e in m/s^2, w_e in rad/s, temp in degC, t in s.
#include <Eigen/Dense>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/case_kind.hpp"
#include "common/frames.hpp"

namespace inertia::dataset {

enum class SensorKind { Accelerometer, Gyroscope };
using inertia::CaseKind;
using inertia::case_kind_from_string;
using inertia::to_string;

using Matrix3Columns = Eigen::Matrix<double, Eigen::Dynamic, 3>;

/// One test case: one mounting of the sensor, one CSV file.
struct CaseData {
  std::string name;
  CaseKind kind = CaseKind::Static;
  std::string file;                                   // CSV file name, relative to the dataset folder
  frames::Dcm m_ec = frames::Dcm::Identity();         // nominal M_E^C (rows: IRA, XRA, YRA in F_E)
  // Optional (extension of the design's dataset.toml): cases with the same label share one sensor
  // mounting, so one unknown case misalignment (e.g. the three shaker orientations of the paper's
  // Fig. 2: the fixture is remounted, the sensor is not). Empty: a mounting of its own.
  std::string mounting;
  // Optional (extension): this case is one contiguous piece of the plan's case `piece_of`, cut
  // where samples were lost (characterize --log; a dataset's rows are uniform in time). The pieces
  // of one case are one case of the plan: one mounting unless labelled otherwise, one weight, and
  // a phase cut by a hole is still one phase (one offset between phases, not one per piece).
  std::string piece_of;
  // Optional (extension, placement_sd_deg): how well the fixture placed this case, the sd per axis
  // of the rotation between its nominal and its true case frame (rad). The analysis propagates it
  // where the data cannot show it (procedure/placement.hpp); 0: placed exactly.
  double placement_sd_rad = 0.0;
  double sample_period_s = 0.0;                       // from the uniform `t` column
  Eigen::VectorXd t;                                  // s
  Matrix3Columns a_e;                                 // reference specific force in F_E, m/s^2
  std::optional<Matrix3Columns> w_e;                  // reference rate in F_E, rad/s
  std::optional<Eigen::VectorXd> temp;                // degC
  Eigen::VectorXd y;                                  // sensor output, in the dataset's output unit
  std::vector<std::string> phase_names;               // distinct labels, in order of first appearance
  std::vector<std::uint16_t> phase;                   // per sample index into phase_names; empty if no column

  [[nodiscard]] Eigen::Index size() const { return t.size(); }
  /// The plan's case these rows belong to: `piece_of`, or the case itself.
  [[nodiscard]] const std::string& plan_case() const { return piece_of.empty() ? name : piece_of; }
  /// The sensor mounting the case shares with others: `mounting`, or its plan case alone.
  [[nodiscard]] const std::string& mounting_group() const { return mounting.empty() ? plan_case() : mounting; }
};

struct Dataset {
  std::filesystem::path dir;                          // where read_dataset found it; empty if built in memory
  SensorKind sensor = SensorKind::Accelerometer;
  std::string sensor_name;                            // optional sensor_name (extension): the bench's name for it
  std::string serial;                                 // optional serial (extension): the unit's serial number
  std::string part;                                   // optional part (extension): its type (part number)
  std::string unit;                                   // optional unit (extension): the [[unit]] it belongs to
  int unit_axis = -1;                                 // optional unit_axis (extension): "x", "y", "z" in that unit; -1: none
  std::string output_unit;
  double t_ref = 25.0;                                // degC; model variable T = temp - t_ref
  std::vector<CaseData> cases;
};

/// Relative tolerance on each time step: |t[k+1] - t[k] - period| <= kTimeJitterTolerance * period,
/// with period = (t[N-1] - t[0]) / (N - 1). Loose enough for times printed with full precision at
/// several minutes and 10 kHz (rounding there is ~1e-9 of the period), tight enough to catch a
/// dropped or repeated sample.
inline constexpr double kTimeJitterTolerance = 1e-6;

/// Tolerance on |M M^T - I| and |det M - 1| for m_ec: a matrix typed with six or more digits
/// passes, a matrix that is not a rotation (a sign error, a transposed row) does not.
inline constexpr double kRotationTolerance = 1e-6;

/// Reads dataset.toml and every case CSV in `dir`. Throws InputError naming file, line and column
/// (1-based field index; the message also names the column) for a non-number, a NaN or infinity,
/// a non-uniform or non-increasing time column, a row with too few or too many fields, a partial
/// w_x/w_y/w_z set (column of the first rate column present), a missing required column (line 1,
/// no column index: the message names the column), a file without data rows, or a bad
/// dataset.toml (line and column of the key; an m_ec that is not a rotation). Blank lines are
/// allowed only at the end, so line = row + 2 always. Unknown columns are ignored with one warning
/// line per column on `warnings`. Thread: any. Speed: the CSV is mapped and parsed in place with
/// std::from_chars, whose own cost dominates (BM_ReadDataset in tests/bench/regressors_benchmark.cpp
/// measures it; docs/validation.md, 'Evidence behind choices in the code').
Dataset read_dataset(const std::filesystem::path& dir, std::ostream& warnings);
Dataset read_dataset(const std::filesystem::path& dir);   // warnings go to std::cerr

/// Reads one case CSV into `out` (t, a_e, w_e, temp, y, phase, sample_period_s); the other fields
/// of `out` are left as they are. `file` is the path used for reading and in error messages.
void read_case_csv(const std::filesystem::path& file, CaseData& out, std::ostream& warnings);

/// dataset.toml alone, with read_dataset's checks of it: every case's description (name, kind,
/// file, m_ec, ...) without its rows, for a reader that streams the case files (CaseRowStream).
Dataset read_dataset_description(const std::filesystem::path& dir);

/// A block of a case file's rows: CaseData's columns over rows [first_row, first_row + size()),
/// its phase labels numbered over the file so far (block.phase_names), its sample_period_s the
/// file's.
using BlockConsumer = std::function<void(const CaseData& block, Eigen::Index first_row)>;

/// One case CSV read a block of rows at a time, for a record too long to hold: the file is mapped
/// and read front to back, each block's pages given back to the system once parsed, so the
/// memory held is a group of blocks' (a few MB of text and its rows each, one block per --jobs
/// thread, which parse a group side by side) whatever the file's length.
class CaseRowStream {
 public:
  /// Reads the header and checks every row: the errors read_case_csv raises, in its order (a bad
  /// field where it is met, the time column once every row has parsed). `check`, when set, sees
  /// each block on this first pass (a reader that needs two passes takes its first here); a block
  /// seen before an error is thrown belongs to a file that is refused.
  CaseRowStream(const std::filesystem::path& file, std::ostream& warnings, const BlockConsumer& check = {});
  ~CaseRowStream();
  CaseRowStream(CaseRowStream&&) noexcept;
  CaseRowStream& operator=(CaseRowStream&&) noexcept;

  [[nodiscard]] Eigen::Index rows() const;
  [[nodiscard]] double sample_period_s() const;
  /// The file's phase labels in order of first appearance (empty: no phase column).
  [[nodiscard]] const std::vector<std::string>& phase_names() const;
  /// The rows again, block by block in order (the file was checked: nothing is thrown for it).
  void for_each_block(const BlockConsumer& consume);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Writes dataset.toml and one CSV per case into `dir` (created if needed). Numbers are written
/// with std::to_chars' shortest round-trip form, so read_dataset gives back the same doubles and
/// the same data always gives the same bytes. Columns: t,a_x,a_y,a_z[,w_x,w_y,w_z][,temp],y[,phase].
/// Phase labels are written as given; a label holding a comma, quote or line break cannot be
/// written into this CSV dialect and throws InputError. Also throws InputError when a case's
/// columns differ in length, and std::filesystem::filesystem_error / std::runtime_error on I/O.
/// Refused with InputError before anything is written when the filesystem lacks the room for it
/// (csv_bytes, common/disk_space.hpp).
void write_dataset(const std::filesystem::path& dir, const Dataset& data);

/// About the bytes of the CSVs write_dataset writes for `data` (each case's first rows formatted,
/// the rest at their mean length).
std::uintmax_t csv_bytes(const Dataset& data);

const char* to_string(SensorKind kind);   // "accelerometer", "gyroscope" (the dataset.toml spelling)
std::optional<SensorKind> sensor_kind_from_string(std::string_view text);

}  // namespace inertia::dataset
