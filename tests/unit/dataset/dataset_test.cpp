// Dataset folder contract (docs/design.md, "Dataset folder"): round trip, deterministic bytes, and a
// file:line:column for every kind of bad CSV or dataset.toml.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/dataset/bench_dataset.hpp"
#include "common/dataset/dataset.hpp"
#include "common/disk_space.hpp"
#include "common/input_error.hpp"
#include "common/parallel.hpp"

namespace inertia::dataset {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(INERTIA_BINARY_DIR) / "test-data" / "dataset" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string slurp(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void spit(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

constexpr const char* kToml = R"(sensor = "accelerometer"
output_unit = "mA"
t_ref = 25.0
[[case]]
name = "c1"
kind = "shaker"
file = "c1.csv"
m_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
)";

// A folder with kToml and `csv` as c1.csv; returns the folder.
fs::path folder_with_csv(const std::string& name, const std::string& csv) {
  const fs::path dir = fresh_dir(name);
  spit(dir / "dataset.toml", kToml);
  spit(dir / "c1.csv", csv);
  return dir;
}

// Reads and returns the InputError; fails the test when nothing is thrown.
InputError read_error(const fs::path& dir) {
  std::ostringstream warnings;
  try {
    read_dataset(dir, warnings);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "read_dataset(" << dir << ") did not throw";
  return InputError("none");
}

Dataset sample_dataset() {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> normal(0.0, 3.0);
  Dataset d;
  d.sensor = SensorKind::Gyroscope;
  d.output_unit = "deg/h \"raw\"";
  d.t_ref = 23.456789012345678;
  CaseData full;
  full.name = "shaker-ia";
  full.kind = CaseKind::Shaker;
  full.file = "shaker-ia.csv";
  full.m_ec = frames::frame_rotation(Eigen::Vector3d(0.3, -1.0, 0.2), 0.7);
  full.mounting = "shaker fixture";
  const Eigen::Index n = 500;
  full.t.resize(n);
  full.a_e.resize(n, 3);
  full.w_e.emplace(n, 3);
  full.temp.emplace(n);
  full.y.resize(n);
  full.phase_names = {"static", "sine 80 Hz", "random"};
  for (Eigen::Index k = 0; k < n; ++k) {
    full.t[k] = 1.25 + static_cast<double>(k) * 1e-4;
    for (int a = 0; a < 3; ++a) {
      full.a_e(k, a) = normal(rng);
      (*full.w_e)(k, a) = normal(rng) * 1e-3;
    }
    (*full.temp)[k] = 20.0 + normal(rng);
    full.y[k] = normal(rng) * 1e-7;   // small numbers need all 17 digits too
    full.phase.push_back(static_cast<std::uint16_t>((k / 100) % 3));
  }
  full.a_e(3, 1) = -0.0;
  full.y[4] = 1e-300;
  CaseData minimal;
  minimal.name = "table";
  minimal.kind = CaseKind::RotationTable;
  minimal.file = "table.csv";
  minimal.t = Eigen::VectorXd::LinSpaced(4, 0.0, 0.3);
  minimal.a_e = Matrix3Columns::Random(4, 3);
  minimal.y = Eigen::VectorXd::Random(4);
  d.cases = {full, minimal};
  return d;
}

TEST(Dataset, RoundTripIsExactAndBytesAreDeterministic) {
  const Dataset d = sample_dataset();
  const fs::path a = fresh_dir("roundtrip-a");
  const fs::path b = fresh_dir("roundtrip-b");
  write_dataset(a, d);
  std::ostringstream warnings;
  const Dataset r = read_dataset(a, warnings);
  EXPECT_EQ(warnings.str(), "");
  EXPECT_EQ(r.sensor, d.sensor);
  EXPECT_EQ(r.output_unit, d.output_unit);
  EXPECT_EQ(r.t_ref, d.t_ref);
  ASSERT_EQ(r.cases.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const CaseData& x = d.cases[i];
    const CaseData& y = r.cases[i];
    EXPECT_EQ(y.name, x.name);
    EXPECT_EQ(y.kind, x.kind);
    EXPECT_EQ(y.file, x.file);
    EXPECT_EQ(y.mounting, x.mounting);
    EXPECT_EQ(y.piece_of, x.piece_of);
    EXPECT_EQ(y.m_ec, x.m_ec);   // bitwise: shortest round-trip digits
    EXPECT_EQ(y.t, x.t);
    EXPECT_EQ(y.a_e, x.a_e);
    EXPECT_EQ(y.y, x.y);
    EXPECT_EQ(y.w_e.has_value(), x.w_e.has_value());
    if (x.w_e) {
      EXPECT_EQ(*y.w_e, *x.w_e);
    }
    EXPECT_EQ(y.temp.has_value(), x.temp.has_value());
    if (x.temp) {
      EXPECT_EQ(*y.temp, *x.temp);
    }
    EXPECT_EQ(y.phase_names, x.phase_names);
    EXPECT_EQ(y.phase, x.phase);
  }
  EXPECT_TRUE(std::signbit(r.cases[0].a_e(3, 1)));
  EXPECT_NEAR(r.cases[0].sample_period_s, 1e-4, 1e-15);
  EXPECT_NEAR(r.cases[1].sample_period_s, 0.1, 1e-15);

  write_dataset(b, r);
  for (const char* file : {"dataset.toml", "shaker-ia.csv", "table.csv"}) {
    EXPECT_EQ(slurp(a / file), slurp(b / file)) << file;
  }
  EXPECT_EQ(slurp(a / "shaker-ia.csv").substr(0, 40), "t,a_x,a_y,a_z,w_x,w_y,w_z,temp,y,phase\n1");
}

// The size write_dataset asks the disk for: a long case whose first rows are shorter than the
// rest (small times, then long ones) is estimated within a few percent of what it writes, and a
// case shorter than the sample exactly.
TEST(Dataset, TheCsvBytesAskedForAreWhatIsWritten) {
  Dataset d = sample_dataset();
  CaseData& long_case = d.cases[1];
  const Eigen::Index n = 200000;
  long_case.t = Eigen::VectorXd::LinSpaced(n, 0.0, 0.001 * double(n - 1));
  long_case.a_e = Matrix3Columns::Random(n, 3);
  long_case.y = Eigen::VectorXd::Random(n);
  const fs::path dir = fresh_dir("csv-bytes");
  write_dataset(dir, d);
  const auto written = double(fs::file_size(dir / "shaker-ia.csv") + fs::file_size(dir / "table.csv"));
  const auto asked = double(csv_bytes(d));
  EXPECT_NEAR(asked, written, 0.03 * written) << asked << " asked, " << written << " written";
  Dataset short_only;
  short_only.cases = {d.cases[0]};
  EXPECT_EQ(csv_bytes(short_only), fs::file_size(dir / "shaker-ia.csv"));
}

// More bytes than the disk has free are refused with both figures, before anything is created;
// what fits is let through. The filesystem is this test's own (its free space read at the call).
TEST(Dataset, AWriteLargerThanTheFreeSpaceIsRefusedWithTheFigures) {
  const fs::path dir = fs::path(INERTIA_BINARY_DIR) / "test-data" / "dataset" / "no-room" / "deeper";
  fs::remove_all(dir.parent_path());
  const std::uintmax_t free = free_bytes_for(dir);
  ASSERT_GT(free, 0U);
  try {
    require_free_space(dir, free + (std::uintmax_t{1} << 40), "dataset " + dir.string());
    ADD_FAILURE() << "a write of a terabyte more than is free was let through";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("to write"), std::string::npos) << what;
    EXPECT_NE(what.find("free"), std::string::npos) << what;
    EXPECT_NE(what.find("MB"), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(dir.parent_path()));
  EXPECT_NO_THROW(require_free_space(dir, 1, "one byte"));
}

TEST(Dataset, AnyColumnOrderCrlfAndUnknownColumnsWarnOncePerColumn) {
  const fs::path dir = folder_with_csv("order", "y, a_z,foo,t,a_y,a_x,bar\r\n"
                                                "1,2,x,0.0,3,4,?\r\n"
                                                "5,6,y,0.5,7,+8,?\r\n"
                                                "9,10,z,1.0,11,12,?\r\n");
  std::ostringstream warnings;
  const Dataset d = read_dataset(dir, warnings);
  const CaseData& c = d.cases.at(0);
  ASSERT_EQ(c.size(), 3);
  EXPECT_EQ(c.y, Eigen::Vector3d(1, 5, 9));
  EXPECT_EQ(c.a_e.col(2), Eigen::Vector3d(2, 6, 10));
  EXPECT_EQ(c.a_e.col(1), Eigen::Vector3d(3, 7, 11));
  EXPECT_EQ(c.a_e.col(0), Eigen::Vector3d(4, 8, 12));
  EXPECT_DOUBLE_EQ(c.sample_period_s, 0.5);
  EXPECT_FALSE(c.w_e.has_value());
  EXPECT_FALSE(c.temp.has_value());
  EXPECT_TRUE(c.phase.empty());
  const std::string w = warnings.str();
  EXPECT_NE(w.find("c1.csv:1:3: warning: unknown column 'foo'"), std::string::npos) << w;
  EXPECT_NE(w.find("c1.csv:1:7: warning: unknown column 'bar'"), std::string::npos) << w;
  EXPECT_EQ(std::count(w.begin(), w.end(), '\n'), 2) << w;
}

struct BadCsv {
  const char* name;
  const char* csv;
  std::size_t line;
  std::size_t column;
  const char* message_part;   // must appear in what()
};

class BadCsvTest : public ::testing::TestWithParam<BadCsv> {};

TEST_P(BadCsvTest, NamesFileLineAndColumn) {
  const BadCsv& bad = GetParam();
  const fs::path dir = folder_with_csv(bad.name, bad.csv);
  const InputError e = read_error(dir);
  EXPECT_EQ(e.where().file, (dir / "c1.csv").string());
  EXPECT_EQ(e.where().line, bad.line) << e.what();
  EXPECT_EQ(e.where().column, bad.column) << e.what();
  EXPECT_NE(std::string(e.what()).find(bad.message_part), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("c1.csv:"), std::string::npos) << e.what();
  // The file streamed: the same error, word for word.
  std::ostringstream warnings;
  try {
    CaseRowStream stream(dir / "c1.csv", warnings);
    ADD_FAILURE() << "the stream read a bad file";
  } catch (const InputError& streamed) {
    EXPECT_STREQ(streamed.what(), e.what());
  }
}

INSTANTIATE_TEST_SUITE_P(
    Dataset, BadCsvTest,
    ::testing::Values(
        BadCsv{"missing_column", "t,a_x,a_z,y\n0,1,2,3\n1,1,2,3\n", 1, 0, "missing required column 'a_y'"},
        BadCsv{"missing_y", "a_x,a_y,a_z,t\n0,1,2,3\n1,1,2,4\n", 1, 0, "'y'"},
        BadCsv{"non_number", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,abc,4\n", 3, 4, "not a number in column 'a_z': 'abc'"},
        BadCsv{"trailing_garbage", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3,4x\n", 3, 5, "column 'y': '4x'"},
        BadCsv{"empty_field", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,,3,4\n", 3, 3, "column 'a_y'"},
        BadCsv{"nan", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3,4\n0.2,1,2,3,nan\n", 4, 5, "nan in column 'y'"},
        BadCsv{"inf", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,-inf,2,3,4\n", 3, 2, "-inf in column 'a_x'"},
        BadCsv{"out_of_range", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1e999,2,3,4\n", 3, 2, "out of range"},
        BadCsv{"non_uniform_t", "a_x,t,a_y,a_z,y\n1,0,2,3,4\n1,0.1,2,3,4\n1,0.2,2,3,4\n1,0.35,2,3,4\n1,0.4,2,3,4\n",
               5, 2, "non-uniform time column 't'"},
        BadCsv{"decreasing_t", "t,a_x,a_y,a_z,y\n1,1,2,3,4\n0,1,2,3,4\n", 3, 1, "does not increase"},
        BadCsv{"w_partial", "t,a_x,a_y,a_z,w_x,w_z,y\n0,1,2,3,4,5,6\n", 1, 5, "w_x, w_z' present but w_y missing"},
        BadCsv{"too_few_fields", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3\n", 3, 5, "column 'y' is missing"},
        BadCsv{"too_many_fields", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3,4,5\n", 3, 6, "more fields"},
        BadCsv{"empty_file", "", 1, 0, "empty file"},
        BadCsv{"header_only", "t,a_x,a_y,a_z,y\n", 1, 0, "no data rows"},
        BadCsv{"blank_line_inside", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n\n0.2,1,2,3,4\n", 3, 0, "empty line"},
        BadCsv{"duplicate_column", "t,a_x,a_y,a_z,y,a_x\n0,1,2,3,4,5\n", 1, 6, "duplicate column 'a_x'"}),
    [](const ::testing::TestParamInfo<BadCsv>& info) { return std::string(info.param.name); });

// Four cases, their files read side by side: the same data and warnings, in case order, as one
// thread gives; with two bad files the error is the first case's, whichever thread ends first.
TEST(Dataset, CasesReadSideBySideGiveTheSerialDataWarningsAndFirstError) {
  const fs::path dir = fresh_dir("side_by_side");
  std::string toml = "sensor = \"accelerometer\"\noutput_unit = \"mA\"\nt_ref = 25.0\n";
  for (int i = 0; i < 4; ++i) {
    toml += fmt::format("[[case]]\nname = \"c{0}\"\nkind = \"shaker\"\nfile = \"c{0}.csv\"\n"
                        "m_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n", i);
    std::string csv = fmt::format("t,a_x,a_y,a_z,y,extra{}\n", i);
    for (int k = 0; k < 2000; ++k) csv += fmt::format("{},{},{},{},{},?\n", 0.001 * k, i + k, 2 * k, 3 * k, 0.5 * k - i);
    spit(dir / fmt::format("c{}.csv", i), csv);
  }
  spit(dir / "dataset.toml", toml);
  const auto read_with = [&](int jobs, std::string& warnings_text) {
    parallel::set_jobs(jobs);
    std::ostringstream warnings;
    Dataset d = read_dataset(dir, warnings);
    parallel::set_jobs(1);
    warnings_text = warnings.str();
    return d;
  };
  std::string serial_warnings, parallel_warnings;
  const Dataset serial = read_with(1, serial_warnings);
  const Dataset side_by_side = read_with(4, parallel_warnings);
  ASSERT_EQ(side_by_side.cases.size(), 4U);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(side_by_side.cases[i].a_e, serial.cases[i].a_e);
    EXPECT_EQ(side_by_side.cases[i].y, serial.cases[i].y);
    EXPECT_EQ(side_by_side.cases[i].a_e(7, 0), static_cast<double>(i + 7));
  }
  EXPECT_EQ(parallel_warnings, serial_warnings);
  EXPECT_LT(parallel_warnings.find("extra0"), parallel_warnings.find("extra3")) << parallel_warnings;

  // c1 fails at its last row, c3 at its first: c1's error, though c3's comes first in time.
  std::string c1 = slurp(dir / "c1.csv");
  c1 += "9,1,2,x,4,?\n";
  spit(dir / "c1.csv", c1);
  spit(dir / "c3.csv", "t,a_x,a_y,a_z,y\n0,1,2,3,abc\n");
  for (const int jobs : {1, 4}) {
    parallel::set_jobs(jobs);
    const InputError e = read_error(dir);
    parallel::set_jobs(1);
    EXPECT_EQ(e.where().file, (dir / "c1.csv").string()) << e.what();
    EXPECT_EQ(e.where().line, 2002U) << e.what();
  }
}

// A case file of several chunks (a reader parses 4 MiB of lines at a time, on the --jobs threads):
// the values, the phase labels numbered in order of first appearance over the whole file though
// each chunk meets them in its own order, and the first bad line's position, with 1 and 2 threads.
TEST(Dataset, AFileReadInChunksGivesTheRowsLabelsAndFirstErrorOfTheWholeFile) {
  const fs::path dir = fresh_dir("chunks");
  spit(dir / "dataset.toml", std::string(kToml));
  constexpr int kRows = 300000;
  const auto label_of = [](int k) {
    // Each third of the file starts with a label the one before did not have, then an old one.
    static const std::array<const char*, 6> labels{"rest", "sine", "rest", "sweep", "sine", "shock"};
    return labels[static_cast<std::size_t>(2 * (k / (kRows / 3)) + (k / 997) % 2)];
  };
  std::string csv = "t,a_x,a_y,a_z,y,phase\n";
  std::vector<std::string> names;
  std::vector<std::uint16_t> phase;
  for (int k = 0; k < kRows; ++k) {
    const std::string label = label_of(k);
    auto it = std::find(names.begin(), names.end(), label);
    if (it == names.end()) it = names.insert(names.end(), label);
    phase.push_back(static_cast<std::uint16_t>(it - names.begin()));
    csv += fmt::format("{},{},{},{},{},{}\n", 0.001 * k, k % 1000, -k, 0.5 * (k % 7), k * 1e-6, label);
  }
  ASSERT_GT(csv.size(), std::size_t{8} << 20) << "at least three chunks";
  spit(dir / "c1.csv", csv);
  for (const int jobs : {1, 2}) {
    parallel::set_jobs(jobs);
    std::ostringstream warnings;
    const Dataset d = read_dataset(dir, warnings);
    parallel::set_jobs(1);
    const CaseData& c = d.cases.at(0);
    ASSERT_EQ(c.size(), kRows);
    EXPECT_EQ(c.phase_names, names) << "jobs " << jobs;
    EXPECT_TRUE(c.phase == phase) << "jobs " << jobs;
    for (const int k : {0, 1, kRows / 3, kRows / 2, kRows - 1}) {
      EXPECT_EQ(c.a_e(k, 0), k % 1000);
      EXPECT_EQ(c.a_e(k, 1), -k);
      EXPECT_EQ(c.y(k), k * 1e-6);
    }
  }
  // Bad lines in the second and the last chunk: the second's is the one named.
  const std::size_t second = csv.find('\n', std::size_t{5} << 20) + 1;
  const std::size_t last = csv.find('\n', csv.size() - 1000) + 1;
  const auto line_at = [&](std::size_t offset) { return 1 + static_cast<std::size_t>(std::count(csv.begin(), csv.begin() + static_cast<std::ptrdiff_t>(offset), '\n')); };
  std::string bad = csv;
  bad.replace(last, bad.find(',', last) - last, "x");
  bad.replace(second, bad.find(',', second) - second, "oops");
  spit(dir / "c1.csv", bad);
  for (const int jobs : {1, 2}) {
    parallel::set_jobs(jobs);
    const InputError e = read_error(dir);
    parallel::set_jobs(1);
    EXPECT_EQ(e.where().line, line_at(second)) << e.what();
    EXPECT_EQ(e.where().column, 1U) << e.what();
  }
  // A blank line in the middle chunk is inside the data, at its own line.
  std::string blank = csv;
  const std::size_t middle = csv.find('\n', csv.size() / 2) + 1;
  blank.insert(middle, "\n");
  spit(dir / "c1.csv", blank);
  parallel::set_jobs(2);
  const InputError e = read_error(dir);
  parallel::set_jobs(1);
  EXPECT_EQ(e.where().line, line_at(middle)) << e.what();
  EXPECT_NE(std::string(e.what()).find("empty line inside the data"), std::string::npos) << e.what();
}

/// The blocks of a streamed case file put back together.
CaseData streamed_whole(const fs::path& file, int* blocks = nullptr) {
  std::ostringstream warnings;
  CaseData whole;
  std::vector<CaseData> parts;
  Eigen::Index checked = 0;
  CaseRowStream stream(file, warnings, [&](const CaseData& block, Eigen::Index first_row) {
    EXPECT_EQ(first_row, checked) << "the check pass sees every row in order";
    checked += block.size();
  });
  EXPECT_EQ(checked, stream.rows());
  Eigen::Index next = 0;
  stream.for_each_block([&](const CaseData& block, Eigen::Index first_row) {
    EXPECT_EQ(first_row, next);
    next += block.size();
    parts.push_back(block);
  });
  if (blocks != nullptr) *blocks = static_cast<int>(parts.size());
  const Eigen::Index n = stream.rows();
  whole.t.resize(n);
  whole.a_e.resize(n, 3);
  whole.y.resize(n);
  if (!parts.empty() && parts.front().temp) whole.temp.emplace(n);
  if (!parts.empty() && parts.front().w_e) whole.w_e.emplace(n, 3);
  Eigen::Index at = 0;
  for (const CaseData& b : parts) {
    whole.t.segment(at, b.size()) = b.t;
    whole.a_e.middleRows(at, b.size()) = b.a_e;
    whole.y.segment(at, b.size()) = b.y;
    if (b.temp) whole.temp->segment(at, b.size()) = *b.temp;
    if (b.w_e) whole.w_e->middleRows(at, b.size()) = *b.w_e;
    whole.phase.insert(whole.phase.end(), b.phase.begin(), b.phase.end());
    at += b.size();
  }
  whole.phase_names = stream.phase_names();
  whole.sample_period_s = stream.sample_period_s();
  return whole;
}

TEST(Dataset, AStreamedFileGivesTheRowsLabelsAndPeriodOfTheWholeRead) {
  const fs::path dir = fresh_dir("streamed");
  Dataset d = sample_dataset();
  // Enough rows for several blocks, the labels of the later ones first met late.
  CaseData& c = d.cases.at(0);
  const Eigen::Index n = 60000;
  c.t = Eigen::VectorXd::LinSpaced(n, 1.25, 1.25 + static_cast<double>(n - 1) * 1e-4);
  c.a_e = Matrix3Columns::Random(n, 3);
  c.w_e = Matrix3Columns::Random(n, 3);
  c.temp = Eigen::VectorXd::Random(n);
  c.y = Eigen::VectorXd::Random(n);
  c.phase.resize(static_cast<std::size_t>(n));
  for (Eigen::Index k = 0; k < n; ++k) c.phase[static_cast<std::size_t>(k)] = static_cast<std::uint16_t>(k < n / 2 ? (k / 100) % 2 : 2);
  write_dataset(dir, d);
  std::ostringstream warnings;
  const Dataset read = read_dataset(dir, warnings);
  const CaseData& expected = read.cases.at(0);
  int blocks = 0;
  parallel::set_jobs(2);   // blocks parsed side by side, taken in order
  const CaseData got = streamed_whole(dir / c.file, &blocks);
  parallel::set_jobs(1);
  EXPECT_GE(blocks, 2) << "the file is more than one block";
  ASSERT_EQ(got.t.size(), expected.t.size());
  EXPECT_EQ(got.t, expected.t);
  EXPECT_EQ(got.a_e, expected.a_e);
  EXPECT_EQ(*got.w_e, *expected.w_e);
  EXPECT_EQ(*got.temp, *expected.temp);
  EXPECT_EQ(got.y, expected.y);
  EXPECT_TRUE(got.phase == expected.phase);
  EXPECT_EQ(got.phase_names, expected.phase_names);
  EXPECT_EQ(got.sample_period_s, expected.sample_period_s);
  // The description alone: the cases without rows.
  const Dataset description = read_dataset_description(dir);
  ASSERT_EQ(description.cases.size(), read.cases.size());
  EXPECT_EQ(description.cases.at(0).file, c.file);
  EXPECT_EQ(description.cases.at(0).size(), 0);
}

TEST(Dataset, AStreamedFileRaisesTheWholeReadsFirstErrorAcrossBlocks) {
  const fs::path dir = fresh_dir("streamed-errors");
  spit(dir / "dataset.toml", std::string(kToml));
  std::string csv = "t,a_x,a_y,a_z,y\n";
  for (int k = 0; k < 400000; ++k) csv += fmt::format("{},{},{},{},{}\n", 0.001 * k, k % 1000, -k, 0.5 * (k % 7), k * 1e-6);
  ASSERT_GT(csv.size(), std::size_t{8} << 20) << "several blocks";
  const std::size_t second = csv.find('\n', std::size_t{5} << 20) + 1;
  const std::size_t last = csv.find('\n', csv.size() - 1000) + 1;
  const auto error_of = [&](const std::string& text, bool streamed) {
    spit(dir / "c1.csv", text);
    if (!streamed) return std::string(read_error(dir).what());
    std::ostringstream warnings;
    try {
      CaseRowStream stream(dir / "c1.csv", warnings);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("none");
  };
  // On one thread and with the blocks parsed side by side.
  for (const int jobs : {1, 2}) {
    parallel::set_jobs(jobs);
    SCOPED_TRACE(jobs);
    // A time step off in the second block and a bad field in the last: the field is named first,
    // as the whole read names it (the time column is checked once every row has parsed).
    std::string both = csv;
    both.replace(last, both.find(',', last) - last, "x");
    both.replace(second, both.find(',', second) - second, "1e3");
    EXPECT_EQ(error_of(both, true), error_of(both, false));
    EXPECT_NE(error_of(both, true).find("not a number in column 't'"), std::string::npos);
    // The time step alone: the row after the step, in the second block.
    std::string step = csv;
    step.replace(second, step.find(',', second) - second, "1e3");
    EXPECT_EQ(error_of(step, true), error_of(step, false));
    EXPECT_NE(error_of(step, true).find("non-uniform time column"), std::string::npos);
    // Trailing blank lines end the data; a blank line inside is named at its line.
    EXPECT_EQ(error_of(csv + "\n\n", true), "none");
    std::string blank = csv;
    blank.insert(second, "\n");
    EXPECT_EQ(error_of(blank, true), error_of(blank, false));
  }
  parallel::set_jobs(1);
}

TEST(Dataset, TrailingBlankLinesAreAllowed) {
  const fs::path dir = folder_with_csv("trailing", "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3,5\n\n\n");
  std::ostringstream warnings;
  EXPECT_EQ(read_dataset(dir, warnings).cases.at(0).size(), 2);
}

TEST(Dataset, PhaseLabelsKeepOrderOfFirstAppearance) {
  const fs::path dir = folder_with_csv("phase", "t,a_x,a_y,a_z,y,phase\n0,1,2,3,4,sine\n1,1,2,3,4,static\n"
                                                "2,1,2,3,4,sine\n3,1,2,3,4,\n");
  std::ostringstream warnings;
  const CaseData c = read_dataset(dir, warnings).cases.at(0);
  EXPECT_EQ(c.phase_names, (std::vector<std::string>{"sine", "static", ""}));
  EXPECT_EQ(c.phase, (std::vector<std::uint16_t>{0, 1, 0, 2}));
}

TEST(Dataset, MecThatIsNotARotationIsRejectedAtItsLine) {
  const std::string csv = "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3,4\n";
  for (const char* m : {"[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]",      // reflection, det -1
                        "[[1.001, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",     // not orthonormal
                        "[[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"}) {   // repeated row
    const fs::path dir = folder_with_csv("bad_mec", csv);
    std::string toml = kToml;
    toml.replace(toml.find("m_ec = ") + 7, std::string::npos, std::string(m) + "\n");
    spit(dir / "dataset.toml", toml);
    const InputError e = read_error(dir);
    EXPECT_EQ(e.where().file, (dir / "dataset.toml").string());
    EXPECT_EQ(e.where().line, 8u) << e.what();
    EXPECT_EQ(e.where().column, 8u) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a rotation"), std::string::npos) << e.what();
  }
  // Six typed digits of a real rotation pass (tolerance 1e-6).
  const fs::path dir = folder_with_csv("good_mec", csv);
  std::string toml = kToml;
  toml.replace(toml.find("m_ec = ") + 7, std::string::npos,
               "[[0.866025, 0.5, 0.0], [-0.5, 0.866025, 0.0], [0.0, 0.0, 1.0]]\n");
  spit(dir / "dataset.toml", toml);
  std::ostringstream warnings;
  EXPECT_NO_THROW(read_dataset(dir, warnings));
}

// Pieces of one case (a log cut by lost samples) are one case of the plan: they round-trip, and
// pieces that disagree in kind, mounting or orientation are refused at the second one's key.
TEST(Dataset, PiecesOfACaseRoundTripAndMustAgree) {
  Dataset d = sample_dataset();
  d.cases[0].piece_of = "shaker-ia";
  CaseData second = d.cases[0];
  second.name = "shaker-ia-seg2";
  second.file = "shaker-ia-seg2.csv";
  d.cases.insert(d.cases.begin() + 1, second);
  const fs::path dir = fresh_dir("pieces");
  write_dataset(dir, d);
  std::ostringstream warnings;
  const Dataset r = read_dataset(dir, warnings);
  ASSERT_EQ(r.cases.size(), 3u);
  EXPECT_EQ(r.cases[1].piece_of, "shaker-ia");
  EXPECT_EQ(r.cases[1].plan_case(), "shaker-ia");
  EXPECT_EQ(r.cases[1].mounting_group(), "shaker fixture");
  EXPECT_EQ(r.cases[2].plan_case(), "table");
  EXPECT_EQ(r.cases[2].mounting_group(), "table");

  d.cases[1].kind = CaseKind::Static;
  write_dataset(dir, d);
  const InputError e = read_error(dir);
  EXPECT_EQ(e.where().file, (dir / "dataset.toml").string());
  EXPECT_GT(e.where().line, 0u) << e.what();
  EXPECT_NE(std::string(e.what()).find("'shaker-ia-seg2' is a piece of 'shaker-ia'"), std::string::npos) << e.what();
}

TEST(Dataset, BadTomlNamesTheKey) {
  const std::string csv = "t,a_x,a_y,a_z,y\n0,1,2,3,4\n0.1,1,2,3,4\n";
  struct Case {
    std::string from, to;
    std::size_t line;
    const char* part;
  };
  for (const Case& c : {Case{"\"accelerometer\"", "\"magnetometer\"", 1, "magnetometer"},
                        Case{"kind = \"shaker\"", "kind = \"centrifuge\"", 6, "centrifuge"},
                        Case{"t_ref = 25.0", "t_ref = \"hot\"", 3, "t_ref"},
                        Case{"file = \"c1.csv\"", "file = \"nope.csv\"", 7, "not found"},
                        Case{"output_unit = \"mA\"\n", "", 0, "missing key 'output_unit'"},
                        Case{"[[case]]", "[[case]", 4, ""}}) {
    const fs::path dir = folder_with_csv("bad_toml", csv);
    std::string toml = kToml;
    toml.replace(toml.find(c.from), c.from.size(), c.to);
    spit(dir / "dataset.toml", toml);
    const InputError e = read_error(dir);
    EXPECT_EQ(e.where().line, c.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.part), std::string::npos) << e.what();
  }
}

TEST(Dataset, CorruptedFilesGiveDataOrAPositionedInputError) {
  // Single-byte corruptions of a valid file: the reader either returns data or names a position
  // inside the file; it never crashes or reads past the end (this also runs under ASan).
  const std::string good = "t,a_x,a_y,a_z,w_x,w_y,w_z,temp,y,phase\n0,1.5,-2,3e-3,0,0,0,25,0.1,sine\n"
                           "0.001,1.25,-2,3e-3,0,0,0,25,0.2,sine\n0.002,1,-2,3e-3,0,0,0,25.5,0.3,rest\n";
  const std::string alphabet = "0123456789.,-+eE \r\nnaif\"x_";
  std::mt19937 rng(7);
  const fs::path dir = folder_with_csv("corrupt", good);
  for (int trial = 0; trial < 300; ++trial) {
    std::string bad = good;
    const std::size_t at = std::uniform_int_distribution<std::size_t>(0, bad.size() - 1)(rng);
    const char c = alphabet[std::uniform_int_distribution<std::size_t>(0, alphabet.size() - 1)(rng)];
    if (trial % 3 == 0) bad.erase(at, 1); else if (trial % 3 == 1) bad[at] = c; else bad.insert(at, 1, c);
    if (trial % 7 == 0) bad.resize(at);   // truncated file
    spit(dir / "c1.csv", bad);
    std::ostringstream warnings;
    try {
      const Dataset d = read_dataset(dir, warnings);
      const CaseData& c1 = d.cases.at(0);
      EXPECT_EQ(c1.a_e.rows(), c1.size());
      EXPECT_EQ(c1.y.size(), c1.size());
      EXPECT_TRUE(c1.t.allFinite() && c1.a_e.allFinite() && c1.y.allFinite());
    } catch (const InputError& e) {
      const std::size_t lines = static_cast<std::size_t>(std::count(bad.begin(), bad.end(), '\n')) + 1;
      EXPECT_LE(e.where().line, lines) << e.what() << "\n" << bad;
    }
  }
}

TEST(Dataset, WriteRejectsLabelsThatWouldBreakTheCsv) {
  Dataset d = sample_dataset();
  d.cases[0].phase_names[1] = "sine, 80 Hz";
  EXPECT_THROW(write_dataset(fresh_dir("bad_label"), d), InputError);
}

TEST(BenchSensorDataset, CarriesTheUnitsMemberAsTheBenchStatesIt) {
  // The simulator's datasets and an event log's fused ones both start here.
  const config::BenchConfig bench = config::load_bench_config(fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-imu.toml");
  const auto gy = static_cast<std::size_t>(
      std::find_if(bench.sensors.begin(), bench.sensors.end(), [](const config::SensorUnderTest& s) { return s.name == "gy"; }) -
      bench.sensors.begin());
  ASSERT_LT(gy, bench.sensors.size());
  const Dataset ds = bench_sensor_dataset(bench, gy);
  EXPECT_EQ(ds.sensor, SensorKind::Gyroscope);
  EXPECT_EQ(ds.sensor_name, "gy");
  EXPECT_EQ(ds.serial, "IMU-1001");
  EXPECT_EQ(ds.part, "MEMS-IMU-6");
  EXPECT_EQ(ds.unit, "imu");
  EXPECT_EQ(ds.unit_axis, 1);
  EXPECT_EQ(ds.output_unit, "rad/s");
  EXPECT_EQ(ds.t_ref, 25.0);
  EXPECT_TRUE(ds.cases.empty());
  EXPECT_THROW((void)bench_sensor_dataset(bench, bench.sensors.size()), std::out_of_range);
}

}  // namespace
}  // namespace inertia::dataset
