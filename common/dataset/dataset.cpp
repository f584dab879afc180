// Dataset folder I/O (docs/design.md, "Dataset folder"). The CSVs are large (10 kHz for minutes, a few
// million rows), so a case file is read into one buffer and parsed in place with std::from_chars;
// nothing allocates per field. Numbers are written with std::to_chars' shortest round-trip form,
// which makes read(write(x)) == x bit for bit and the bytes a function of the data alone.
#include "common/dataset/dataset.hpp"
#include "common/toml_text.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <system_error>
#include <vector>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <fmt/format.h>

#include "common/dataset/huge_pages.hpp"
#include "common/disk_space.hpp"
#include "common/input_error.hpp"
#include "common/parallel.hpp"
#include "common/units.hpp"

namespace inertia::dataset {

const char* to_string(SensorKind kind) {
  switch (kind) {
    case SensorKind::Accelerometer: return "accelerometer";
    case SensorKind::Gyroscope: return "gyroscope";
  }
  return "?";
}

std::optional<SensorKind> sensor_kind_from_string(std::string_view text) {
  for (SensorKind k : {SensorKind::Accelerometer, SensorKind::Gyroscope}) {
    if (text == to_string(k)) return k;
  }
  return std::nullopt;
}

namespace {

// ---------------------------------------------------------------------------------------------
// Reading one case CSV

enum class Column : std::uint8_t { T, Ax, Ay, Az, Wx, Wy, Wz, Temp, Y, Phase, Unknown };
constexpr std::array<std::string_view, 10> kColumnNames = {"t",   "a_x", "a_y",  "a_z", "w_x",
                                                           "w_y", "w_z", "temp", "y",   "phase"};

Column column_from_name(std::string_view name) {
  for (std::size_t i = 0; i < kColumnNames.size(); ++i) {
    if (name == kColumnNames[i]) return static_cast<Column>(i);
  }
  return Column::Unknown;
}

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && (is_blank(s.back()) || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// The file's bytes, mapped read-only (the page cache already holds them after the first read, so
// this avoids copying hundreds of MB into fresh anonymous pages); read into a string where mmap
// is not possible (a pipe, an empty file).
class FileBytes {
 public:
  /// `whole`: the file is read in at once (MAP_POPULATE); otherwise pages come in as they are
  /// read and release_before() gives them back, so a file read front to back holds a few pages.
  explicit FileBytes(const std::filesystem::path& file, bool whole = true) {
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      throw InputError(SourcePosition{file.string(), 0, 0},
                       fmt::format("cannot open for reading: {}", std::strerror(errno)));
    }
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
      void* p = ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ, MAP_PRIVATE | (whole ? MAP_POPULATE : 0), fd, 0);
      if (p != MAP_FAILED) {
        (void)::madvise(p, static_cast<std::size_t>(st.st_size), MADV_SEQUENTIAL);
        map_ = static_cast<const char*>(p);
        size_ = static_cast<std::size_t>(st.st_size);
        ::close(fd);
        return;
      }
    }
    std::array<char, 1 << 16> chunk;
    ssize_t got = 0;
    while ((got = ::read(fd, chunk.data(), chunk.size())) > 0) copy_.append(chunk.data(), static_cast<std::size_t>(got));
    const int read_errno = errno;
    ::close(fd);
    if (got < 0) {
      throw InputError(SourcePosition{file.string(), 0, 0}, fmt::format("read error: {}", std::strerror(read_errno)));
    }
  }
  ~FileBytes() {
    if (map_ != nullptr) ::munmap(const_cast<char*>(map_), size_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;

  [[nodiscard]] const char* data() const { return map_ != nullptr ? map_ : copy_.data(); }
  [[nodiscard]] std::size_t size() const { return map_ != nullptr ? size_ : copy_.size(); }

  /// The mapped pages wholly before `p` leave the process (read again from the page cache if
  /// touched later): what a pass front to back has read no longer counts in its memory.
  void release_before(const char* p) {
    if (map_ == nullptr || p <= map_) return;
    const auto page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
    const std::size_t end = static_cast<std::size_t>(p - map_) / page * page;
    if (end > released_) {
      (void)::madvise(const_cast<char*>(map_) + released_, end - released_, MADV_DONTNEED);
      released_ = end;
    }
  }
  /// Every page may be read again (a second pass).
  void rewind() { released_ = 0; }

 private:
  const char* map_ = nullptr;
  std::size_t size_ = 0;
  std::size_t released_ = 0;
  std::string copy_;
};

// One field's text, for error messages: up to the next comma or the end of the line.
std::string_view field_text(const char* p, const char* eol) {
  const char* q = static_cast<const char*>(std::memchr(p, ',', static_cast<std::size_t>(eol - p)));
  return trim(std::string_view(p, static_cast<std::size_t>((q ? q : eol) - p)));
}

/// The sample period of a case file's `rows` rows from its first and last time; throws for fewer
/// than two rows or a time that does not increase.
double sample_period(const std::string& file, std::size_t t_col, Eigen::Index rows, double first_t, double last_t) {
  if (rows < 2) {
    throw InputError(SourcePosition{file, rows == 0 ? 1u : 2u, 0},
                     fmt::format("{} data row{}: at least two rows are needed to define the sample period",
                                 rows == 0 ? "no" : "only one", rows == 1 ? "" : "s"));
  }
  const double period = (last_t - first_t) / static_cast<double>(rows - 1);
  if (!(period > 0.0)) {
    throw InputError(SourcePosition{file, 2 + static_cast<std::size_t>(rows - 1), t_col},
                     "time column 't' does not increase (last time <= first time)");
  }
  return period;
}

/// The first step of times `t` (rows first_row.., after `previous`, the row before's time if
/// any) that differs from `period` by more than kTimeJitterTolerance of it, as the error to throw.
std::optional<InputError> uneven_step(const std::string& file, std::size_t t_col, const Eigen::Ref<const Eigen::VectorXd>& t,
                                      Eigen::Index first_row, std::optional<double> previous, double period) {
  const double tolerance = kTimeJitterTolerance * period;
  for (Eigen::Index k = previous ? -1 : 0; k + 1 < t.size(); ++k) {
    const double step = t[k + 1] - (k < 0 ? *previous : t[k]);
    if (std::abs(step - period) > tolerance) {
      return InputError(SourcePosition{file, 3 + static_cast<std::size_t>(first_row + k), t_col},
                        fmt::format("non-uniform time column 't': step {} s from the previous row differs from the "
                                    "mean period {} s by more than the relative jitter tolerance {}",
                                    step, period, kTimeJitterTolerance));
    }
  }
  return std::nullopt;
}

/// Every column of `c` cut to its first `rows` rows.
void keep_first_rows(CaseData& c, Eigen::Index rows) {
  c.t.conservativeResize(rows);
  c.a_e.conservativeResize(rows, 3);
  c.y.conservativeResize(rows);
  if (c.w_e) c.w_e->conservativeResize(rows, 3);
  if (c.temp) c.temp->conservativeResize(rows);
  if (!c.phase.empty()) c.phase.resize(static_cast<std::size_t>(rows));
}

// One case file being read: its bytes, the header's columns, the outputs sized from the count of
// lines, and the rows split into chunks of whole lines. A chunk parses on its own into its own rows
// (line = row + 2, so every position is known before parsing), which lets the chunks of every case
// of a dataset run on the --jobs threads; its phase labels are numbered within the chunk and
// renumbered in order of first appearance when the case is finished.
class CaseCsv {
 public:
  /// Reads the header and cuts the rows into chunks. `out`'s columns are sized for every row
  /// (read whole), or, with `whole` false, left alone: the chunks are then parsed one at a time
  /// into blocks of their own (parse_chunk_into), the file read front to back.
  CaseCsv(const std::filesystem::path& file, CaseData& out, std::ostream& warnings, bool whole = true);

  [[nodiscard]] std::size_t chunks() const { return chunks_.size(); }
  /// Parses chunk `c` into its rows of `out`. Throws InputError at the chunk's first bad line.
  void parse_chunk(std::size_t c);
  /// Parses chunk `c` into `block`, sized to the chunk's rows (fewer when a trailing blank line
  /// ends the data in it); phase labels are numbered within the chunk (chunk_phase_names).
  void parse_chunk_into(std::size_t c, CaseData& block);
  [[nodiscard]] Eigen::Index chunk_first_row(std::size_t c) const { return chunks_.at(c).first_row; }
  [[nodiscard]] const std::vector<std::string>& chunk_phase_names(std::size_t c) const { return chunks_.at(c).phase_names; }
  /// The chunk's labels (count of them, from its first row) numbered over the file: `names` gets
  /// the labels not met before, in order of first appearance.
  void number_phases_over_file(std::size_t c, std::vector<std::string>& names, std::uint16_t* labels, Eigen::Index count) const;
  /// The pages of the chunks before `c` leave the process (whole = false).
  void release_before_chunk(std::size_t c) { buf_.release_before(chunks_.at(c).begin); }
  /// For another pass from the first chunk.
  void rewind() { buf_.rewind(); }
  /// After every chunk parsed: the phase labels numbered over the file, trailing blank lines
  /// dropped, the time column checked and the sample period set.
  void finish();
  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] std::size_t time_column() const { return where_[static_cast<std::size_t>(Column::T)]; }

 private:
  // Lines of up to this many bytes per chunk: a few per case for the threads to share, and few
  // enough that their labels and bookkeeping cost nothing.
  static constexpr std::size_t kChunkBytes = std::size_t{4} << 20;

  struct Chunk {
    const char* begin = nullptr;
    const char* end = nullptr;
    Eigen::Index first_row = 0, end_row = 0;   // its rows: [first_row, end_row)
    Eigen::Index blank_row = -1;   // the row of the first (trailing) blank line it met; -1: none
    std::vector<std::string> phase_names;   // in order of first appearance in the chunk
    std::vector<Eigen::Index> phase_first_row;   // the row each of them first appears on
  };

  [[nodiscard]] const char* next_eol(const char* from) const {
    const char* q = static_cast<const char*>(std::memchr(from, '\n', static_cast<std::size_t>(end_ - from)));
    return q ? q : end_;
  }

  std::string name_;
  FileBytes buf_;
  const char* end_ = nullptr;
  CaseData& out_;
  std::vector<Column> columns_;
  std::vector<std::string> column_names_;
  std::array<std::size_t, kColumnNames.size()> where_{};  // 1-based field index of each known column, 0 if absent
  std::vector<double*> dest_;
  Eigen::Index rows_ = 0;   // lines after the header, trailing blank ones included
  std::vector<Chunk> chunks_;

  /// Where each field of a row goes in `c`'s columns (nullptr: not a number column).
  [[nodiscard]] std::vector<double*> destinations(CaseData& c) const;
  /// Sizes `c`'s columns for `rows` rows, the columns this file has.
  void size_columns(CaseData& c, Eigen::Index rows) const;
  /// Parses `chunk`'s rows: row r's fields to dest[field][r - offset], its phase to phase[r - offset].
  void parse_rows(Chunk& chunk, const std::vector<double*>& dest, std::uint16_t* phase, Eigen::Index offset);
};

std::vector<double*> CaseCsv::destinations(CaseData& c) const {
  std::vector<double*> dest(columns_.size(), nullptr);
  for (std::size_t i = 0; i < columns_.size(); ++i) {
    switch (columns_[i]) {
      case Column::T: dest[i] = c.t.data(); break;
      case Column::Ax: dest[i] = c.a_e.col(0).data(); break;
      case Column::Ay: dest[i] = c.a_e.col(1).data(); break;
      case Column::Az: dest[i] = c.a_e.col(2).data(); break;
      case Column::Wx: dest[i] = c.w_e->col(0).data(); break;
      case Column::Wy: dest[i] = c.w_e->col(1).data(); break;
      case Column::Wz: dest[i] = c.w_e->col(2).data(); break;
      case Column::Temp: dest[i] = c.temp->data(); break;
      case Column::Y: dest[i] = c.y.data(); break;
      case Column::Phase: case Column::Unknown: break;
    }
  }
  return dest;
}

void CaseCsv::size_columns(CaseData& c, Eigen::Index rows) const {
  const auto has = [&](Column col) { return where_[static_cast<std::size_t>(col)] != 0; };
  c.t.resize(rows);
  c.a_e.resize(rows, 3);
  c.y.resize(rows);
  if (has(Column::Wx)) {
    if (c.w_e) c.w_e->resize(rows, 3); else c.w_e.emplace(rows, 3);
  } else {
    c.w_e.reset();
  }
  if (has(Column::Temp)) {
    if (c.temp) c.temp->resize(rows); else c.temp.emplace(rows);
  } else {
    c.temp.reset();
  }
  c.phase.clear();
  if (has(Column::Phase)) c.phase.resize(static_cast<std::size_t>(rows));
}

CaseCsv::CaseCsv(const std::filesystem::path& file, CaseData& out, std::ostream& warnings, bool whole)
    : name_(file.string()), buf_(file, whole), end_(buf_.data() + buf_.size()), out_(out) {
  const char* p = buf_.data();
  if (buf_.size() >= 3 && std::memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3;  // UTF-8 BOM from spreadsheets

  // Header.
  const char* header_end = next_eol(p);
  const std::string_view header = trim(std::string_view(p, static_cast<std::size_t>(header_end - p)));
  if (header.empty()) {
    throw InputError(SourcePosition{name_, 1, 0},
                     "empty file or empty header row: expected a header such as 't,a_x,a_y,a_z,y'");
  }
  for (std::size_t start = 0;;) {
    const std::size_t comma = header.find(',', start);
    const std::string_view field =
        trim(header.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    const std::size_t index = columns_.size() + 1;
    if (field.empty()) {
      throw InputError(SourcePosition{name_, 1, index}, fmt::format("empty column name in field {}", index));
    }
    const Column c = column_from_name(field);
    if (c == Column::Unknown) {
      warnings << fmt::format("{}:1:{}: warning: unknown column '{}' ignored\n", name_, index, field);
    } else if (where_[static_cast<std::size_t>(c)] != 0) {
      throw InputError(SourcePosition{name_, 1, index},
                       fmt::format("duplicate column '{}' (also field {})", field,
                                   where_[static_cast<std::size_t>(c)]));
    } else {
      where_[static_cast<std::size_t>(c)] = index;
    }
    columns_.push_back(c);
    column_names_.emplace_back(field);
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  const auto has = [&](Column c) { return where_[static_cast<std::size_t>(c)] != 0; };
  for (Column c : {Column::T, Column::Ax, Column::Ay, Column::Az, Column::Y}) {
    if (!has(c)) {
      throw InputError(SourcePosition{name_, 1, 0},
                       fmt::format("missing required column '{}' (header: '{}'; required: t, a_x, a_y, a_z, y)",
                                   kColumnNames[static_cast<std::size_t>(c)], header));
    }
  }
  const int rate_columns = int{has(Column::Wx)} + int{has(Column::Wy)} + int{has(Column::Wz)};
  if (rate_columns != 0 && rate_columns != 3) {
    std::string present, missing;
    std::size_t first = 0;
    for (Column c : {Column::Wx, Column::Wy, Column::Wz}) {
      std::string& list = has(c) ? present : missing;
      if (!list.empty()) list += ", ";
      list += kColumnNames[static_cast<std::size_t>(c)];
      if (has(c) && first == 0) first = where_[static_cast<std::size_t>(c)];
    }
    throw InputError(SourcePosition{name_, 1, first},
                     fmt::format("column '{}' present but {} missing: rate columns w_x, w_y, w_z come as all three or none",
                                 present, missing));
  }

  // Size the outputs from the number of line breaks (one pass of memchr, then no reallocation),
  // and cut the lines into chunks on the way.
  const char* body = header_end == end_ ? end_ : header_end + 1;
  for (const char* q = body; q < end_;) {
    if (chunks_.empty() || q - chunks_.back().begin >= static_cast<std::ptrdiff_t>(kChunkBytes)) {
      if (!chunks_.empty()) chunks_.back().end = q;
      if (!whole) buf_.release_before(q);   // counted: its pages are not needed until parsed
      Chunk next;
      next.begin = q;
      next.end = end_;
      next.first_row = rows_;
      chunks_.push_back(std::move(next));
    }
    const char* e = next_eol(q);
    ++rows_;
    q = e == end_ ? end_ : e + 1;
  }
  for (std::size_t c = 0; c < chunks_.size(); ++c) chunks_[c].end_row = c + 1 < chunks_.size() ? chunks_[c + 1].first_row : rows_;
  out_.phase_names.clear();
  if (!whole) return;
  size_columns(out_, rows_);
  const auto advise = [](auto& m) { advise_huge_pages(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double)); };
  advise(out_.t);
  advise(out_.a_e);
  advise(out_.y);
  if (out_.w_e) advise(*out_.w_e);
  if (out_.temp) advise(*out_.temp);
  dest_ = destinations(out_);
}

void CaseCsv::parse_chunk(std::size_t index) {
  parse_rows(chunks_.at(index), dest_, out_.phase.empty() ? nullptr : out_.phase.data(), 0);
}

void CaseCsv::parse_chunk_into(std::size_t index, CaseData& block) {
  Chunk& chunk = chunks_.at(index);
  size_columns(block, chunk.end_row - chunk.first_row);
  block.phase_names.clear();
  parse_rows(chunk, destinations(block), block.phase.empty() ? nullptr : block.phase.data(), chunk.first_row);
  if (chunk.blank_row >= 0) keep_first_rows(block, chunk.blank_row - chunk.first_row);   // the data end inside this chunk
}

void CaseCsv::parse_rows(Chunk& chunk, const std::vector<double*>& dest, std::uint16_t* phase, Eigen::Index offset) {
  chunk.blank_row = -1;
  chunk.phase_names.clear();
  chunk.phase_first_row.clear();
  std::size_t last_phase = 0;
  // Rows. A row is line `row + 2`; blank lines are allowed only at the end of the file so that
  // this mapping (used in every error message) stays exact.
  Eigen::Index row = chunk.first_row;
  for (const char* q = chunk.begin; q < chunk.end;) {
    const char* eol = next_eol(q);
    const char* next = eol == end_ ? end_ : eol + 1;
    const std::size_t line = static_cast<std::size_t>(row) + 2;
    const char* le = eol;
    if (le > q && le[-1] == '\r') --le;
    if (trim(std::string_view(q, static_cast<std::size_t>(le - q))).empty()) {
      for (const char* r = next; r < end_; ++r) {
        if (!is_blank(*r) && *r != '\r' && *r != '\n') {
          throw InputError(SourcePosition{name_, line, 0}, "empty line inside the data");
        }
      }
      chunk.blank_row = row;
      return;
    }
    const char* f = q;
    for (std::size_t c = 0; c < columns_.size(); ++c) {
      // Built only for an error: a position holds the file's name, and rows run to millions.
      const auto here = [&] { return SourcePosition{name_, line, c + 1}; };
      if (c > 0) {
        if (f >= le || *f != ',') {
          throw InputError(here(), fmt::format("row has {} fields, the header has {}: column '{}' is missing",
                                               c, columns_.size(), column_names_[c]));
        }
        ++f;
      }
      if (double* d = dest[c]) {
        while (f < le && is_blank(*f)) ++f;
        const char* start = f;
        if (f < le && *f == '+') ++f;  // from_chars refuses a leading '+', other writers emit it
        double v = 0.0;
        const auto [ptr, ec] = std::from_chars(f, le, v);
        const char* after = ptr;
        while (after < le && is_blank(*after)) ++after;
        if (ec == std::errc::result_out_of_range) {
          throw InputError(here(), fmt::format("number out of range in column '{}': '{}'", column_names_[c],
                                               field_text(start, le)));
        }
        if (ec != std::errc() || ptr == f || (after < le && *after != ',')) {
          throw InputError(here(), fmt::format("not a number in column '{}': '{}'", column_names_[c],
                                               field_text(start, le)));
        }
        if (!std::isfinite(v)) {
          throw InputError(here(), fmt::format("{} in column '{}': every value must be finite", field_text(start, le),
                                               column_names_[c]));
        }
        d[row - offset] = v;
        f = after;
      } else {
        const char* comma = static_cast<const char*>(std::memchr(f, ',', static_cast<std::size_t>(le - f)));
        const char* field_end = comma ? comma : le;
        if (columns_[c] == Column::Phase) {
          const std::string_view label(f, static_cast<std::size_t>(field_end - f));
          std::vector<std::string>& names = chunk.phase_names;
          if (last_phase >= names.size() || names[last_phase] != label) {
            const auto it = std::find(names.begin(), names.end(), label);
            if (it == names.end()) {
              if (names.size() > 0xFFFF) throw InputError(here(), "more than 65536 distinct phase labels");
              names.emplace_back(label);
              chunk.phase_first_row.push_back(row);
              last_phase = names.size() - 1;
            } else {
              last_phase = static_cast<std::size_t>(it - names.begin());
            }
          }
          phase[row - offset] = static_cast<std::uint16_t>(last_phase);
        }
        f = field_end;
      }
    }
    if (f < le) {
      throw InputError(SourcePosition{name_, line, columns_.size() + 1},
                       fmt::format("row has more fields than the header's {}", columns_.size()));
    }
    ++row;
    q = next;
  }
}

void CaseCsv::finish() {
  Eigen::Index row = rows_;
  for (const Chunk& chunk : chunks_) {
    if (chunk.blank_row >= 0) {
      row = chunk.blank_row;
      break;
    }
  }
  // The labels over the file in order of first appearance: each chunk's, in chunk order.
  if (!out_.phase.empty()) {
    for (std::size_t c = 0; c < chunks_.size(); ++c) {
      const Chunk& chunk = chunks_[c];
      if (chunk.first_row >= row) break;
      number_phases_over_file(c, out_.phase_names, out_.phase.data() + chunk.first_row, std::min(row, chunk.end_row) - chunk.first_row);
    }
  }

  if (row < rows_) keep_first_rows(out_, row);   // trailing blank lines were counted
  out_.sample_period_s = sample_period(name_, time_column(), row, row > 0 ? out_.t[0] : 0.0, row > 0 ? out_.t[row - 1] : 0.0);
  if (const std::optional<InputError> step = uneven_step(name_, time_column(), out_.t.head(row), 0, std::nullopt, out_.sample_period_s))
    throw *step;
}

void CaseCsv::number_phases_over_file(std::size_t c, std::vector<std::string>& names, std::uint16_t* labels, Eigen::Index count) const {
  const Chunk& chunk = chunks_.at(c);
  std::vector<std::uint16_t> renumber(chunk.phase_names.size(), 0);
  bool same = true;
  for (std::size_t local = 0; local < chunk.phase_names.size(); ++local) {
    const auto it = std::find(names.begin(), names.end(), chunk.phase_names[local]);
    const auto global = static_cast<std::size_t>(it - names.begin());
    if (it == names.end()) {
      if (names.size() > 0xFFFF) {
        throw InputError(SourcePosition{name_, static_cast<std::size_t>(chunk.phase_first_row[local]) + 2,
                                        where_[static_cast<std::size_t>(Column::Phase)]},
                         "more than 65536 distinct phase labels");
      }
      names.push_back(chunk.phase_names[local]);
    }
    renumber[local] = static_cast<std::uint16_t>(global);
    same = same && global == local;
  }
  if (same) return;
  for (Eigen::Index k = 0; k < count; ++k) labels[k] = renumber[labels[k]];
}

}  // namespace

void read_case_csv(const std::filesystem::path& file, CaseData& out, std::ostream& warnings) {
  CaseCsv csv(file, out, warnings);
  // The chunks start in index order, so the error rethrown (the first by index) is the file's first.
  parallel::for_each_index(static_cast<long>(csv.chunks()), [&](long c) { csv.parse_chunk(static_cast<std::size_t>(c)); });
  csv.finish();
}

namespace {

// ---------------------------------------------------------------------------------------------
// dataset.toml

SourcePosition position_of(const toml::node& node, const std::string& file) {
  const auto& b = node.source().begin;
  return SourcePosition{file, b.line, b.column};
}

const toml::node& require(const toml::table& table, std::string_view key, const std::string& file,
                          const std::string& context) {
  const toml::node* node = table.get(key);
  if (node == nullptr) {
    // A [[case]] table points at its header line; the root table has no useful position.
    const SourcePosition where = table.is_inline() || context.empty() ? SourcePosition{file, 0, 0}
                                                                      : position_of(table, file);
    throw InputError(where, fmt::format("missing key '{}'{}", key, context));
  }
  return *node;
}

const char* type_name(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a float";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::array: return "an array";
    case toml::node_type::table: return "a table";
    default: return "a date or time";
  }
}

std::string require_string(const toml::table& table, std::string_view key, const std::string& file,
                           const std::string& context = {}) {
  const toml::node& node = require(table, key, file, context);
  if (const auto v = node.value<std::string>(); v && node.is_string()) return *v;
  throw InputError(position_of(node, file), fmt::format("'{}' must be a string, got {}", key, type_name(node)));
}

double to_finite_double(const toml::node& node, const std::string& file, std::string_view what) {
  if (node.is_number()) {
    if (const auto v = node.value<double>(); v && std::isfinite(*v)) return *v;
  }
  throw InputError(position_of(node, file), fmt::format("{} must be a finite number", what));
}

frames::Dcm read_matrix3(const toml::node& node, const std::string& file, std::string_view key) {
  const toml::array* rows = node.as_array();
  const auto bad = [&](const toml::node& at) {
    return InputError(position_of(at, file), fmt::format("'{}' must be a 3x3 array of numbers, [[..], [..], [..]]", key));
  };
  if (rows == nullptr || rows->size() != 3) throw bad(node);
  frames::Dcm m;
  for (int r = 0; r < 3; ++r) {
    const toml::array* row = (*rows)[static_cast<std::size_t>(r)].as_array();
    if (row == nullptr || row->size() != 3) throw bad((*rows)[static_cast<std::size_t>(r)]);
    for (int c = 0; c < 3; ++c) {
      m(r, c) = to_finite_double((*row)[static_cast<std::size_t>(c)], file, fmt::format("'{}' entry", key));
    }
  }
  return m;
}


void append_double(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}


constexpr std::size_t kWriteChunk = std::size_t{1} << 20;

/// A case CSV's header line (the columns the case has).
std::string csv_header(const CaseData& c) {
  std::string csv = "t,a_x,a_y,a_z";
  if (c.w_e) csv += ",w_x,w_y,w_z";
  if (c.temp) csv += ",temp";
  csv += ",y";
  if (!c.phase.empty()) csv += ",phase";
  csv += '\n';
  return csv;
}

/// Row k of a case's CSV, appended to `csv`.
void append_csv_row(std::string& csv, const CaseData& c, Eigen::Index k) {
  append_double(csv, c.t[k]);
  for (int a = 0; a < 3; ++a) { csv += ','; append_double(csv, c.a_e(k, a)); }
  if (c.w_e) {
    for (int a = 0; a < 3; ++a) { csv += ','; append_double(csv, (*c.w_e)(k, a)); }
  }
  if (c.temp) { csv += ','; append_double(csv, (*c.temp)[k]); }
  csv += ',';
  append_double(csv, c.y[k]);
  if (!c.phase.empty()) {
    csv += ',';
    csv += c.phase_names[c.phase[static_cast<std::size_t>(k)]];
  }
  csv += '\n';
}

void write_file(const std::filesystem::path& file, const std::string& bytes) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.c_str(), "wb"), &std::fclose);
  if (!f) {
    throw std::system_error(errno, std::generic_category(), "cannot open " + file.string() + " for writing");
  }
  if (std::fwrite(bytes.data(), 1, bytes.size(), f.get()) != bytes.size() || std::fflush(f.get()) != 0) {
    throw std::system_error(errno, std::generic_category(), "cannot write " + file.string());
  }
}

}  // namespace

Dataset read_dataset(const std::filesystem::path& dir) { return read_dataset(dir, std::cerr); }

namespace {

/// The cases' CSV files after every check of dataset.toml: the headers in case order, then the
/// chunks of every file on the --jobs threads, then each case finished in order. What is thrown
/// and the warnings written are what reading one file after the other gives: the first error by
/// case and line, the warnings of the cases up to it.
void read_case_files(const std::vector<std::filesystem::path>& files, std::vector<CaseData>& cases, std::ostream& warnings) {
  const std::size_t count = files.size();
  std::vector<std::optional<CaseCsv>> readers(count);
  std::vector<std::ostringstream> case_warnings(count);
  std::exception_ptr header_error;
  std::size_t opened = 0;   // the cases whose header read; the next one's failed, if any
  for (; opened < count; ++opened) {
    try {
      readers[opened].emplace(files[opened], cases[opened], case_warnings[opened]);
    } catch (...) {
      header_error = std::current_exception();
      break;
    }
  }
  struct Work {
    std::size_t file = 0, chunk = 0;
    std::exception_ptr error;
  };
  std::vector<Work> work;
  for (std::size_t i = 0; i < opened; ++i)
    for (std::size_t c = 0; c < readers[i]->chunks(); ++c) work.push_back({i, c, nullptr});
  // Once a chunk fails, the later files' chunks are not parsed: their errors would come after it.
  std::atomic<std::size_t> first_failed_file{count};
  parallel::for_each_index(static_cast<long>(work.size()), [&](long index) {
    Work& w = work[static_cast<std::size_t>(index)];
    if (w.file > first_failed_file.load()) return;
    try {
      readers[w.file]->parse_chunk(w.chunk);
    } catch (...) {
      w.error = std::current_exception();
      std::size_t seen = first_failed_file.load();
      while (w.file < seen && !first_failed_file.compare_exchange_weak(seen, w.file)) {
      }
    }
  });
  std::size_t next_work = 0;
  for (std::size_t i = 0; i < opened; ++i) {
    warnings << case_warnings[i].str();
    for (; next_work < work.size() && work[next_work].file == i; ++next_work)
      if (work[next_work].error) std::rethrow_exception(work[next_work].error);
    readers[i]->finish();
    readers[i].reset();   // its file unmapped
  }
  if (header_error) {
    warnings << case_warnings[opened].str();
    std::rethrow_exception(header_error);
  }
}

}  // namespace

Dataset read_dataset(const std::filesystem::path& dir, std::ostream& warnings) {
  Dataset data = read_dataset_description(dir);
  std::vector<std::filesystem::path> csv_files;
  for (const CaseData& c : data.cases) csv_files.push_back(dir / c.file);
  read_case_files(csv_files, data.cases, warnings);
  return data;
}

Dataset read_dataset_description(const std::filesystem::path& dir) {
  const std::filesystem::path toml_path = dir / "dataset.toml";
  const std::string file = toml_path.string();
  toml::table root;
  try {
    root = toml::parse_file(file);
  } catch (const toml::parse_error& e) {
    const auto& b = e.source().begin;
    throw InputError(SourcePosition{file, b.line, b.column}, std::string(e.description()));
  }

  Dataset data;
  data.dir = dir;
  {
    const std::string sensor = require_string(root, "sensor", file);
    const auto kind = sensor_kind_from_string(sensor);
    if (!kind) {
      throw InputError(position_of(*root.get("sensor"), file),
                       fmt::format("sensor = \"{}\" is not one of \"accelerometer\", \"gyroscope\"", sensor));
    }
    data.sensor = *kind;
  }
  data.output_unit = require_string(root, "output_unit", file);
  if (root.get("sensor_name") != nullptr) data.sensor_name = require_string(root, "sensor_name", file);
  if (root.get("serial") != nullptr) data.serial = require_string(root, "serial", file);
  if (root.get("part") != nullptr) data.part = require_string(root, "part", file);
  if (root.get("unit") != nullptr) {
    data.unit = require_string(root, "unit", file);
    const std::string axis = root.get("unit_axis") != nullptr ? require_string(root, "unit_axis", file) : std::string();
    if (axis != "x" && axis != "y" && axis != "z")
      throw InputError(SourcePosition{file, 0, 0}, "unit_axis must be \"x\", \"y\" or \"z\" where unit is given");
    data.unit_axis = axis[0] - 'x';
  }
  data.t_ref = to_finite_double(require(root, "t_ref", file, ""), file, "'t_ref'");

  if (root.get("case") == nullptr) {
    throw InputError(SourcePosition{file, 0, 0}, "no [[case]] table: a dataset has one or more cases");
  }
  const toml::node& cases_node = *root.get("case");
  const toml::array* cases = cases_node.as_array();
  if (cases == nullptr || cases->empty() || !cases->is_array_of_tables()) {
    throw InputError(position_of(cases_node, file), "'case' must be one or more [[case]] tables");
  }
  for (const toml::node& node : *cases) {
    const toml::table& table = *node.as_table();
    CaseData c;
    const std::string where = fmt::format(" in [[case]] at line {}", table.source().begin.line);
    c.name = require_string(table, "name", file, where);
    for (const CaseData& other : data.cases) {
      if (other.name == c.name) {
        throw InputError(position_of(*table.get("name"), file), fmt::format("duplicate case name '{}'", c.name));
      }
    }
    const std::string kind = require_string(table, "kind", file, where);
    const auto case_kind = case_kind_from_string(kind);
    if (!case_kind) {
      throw InputError(position_of(*table.get("kind"), file),
                       fmt::format("kind = \"{}\" is not one of rotation_table, shaker, thermal, static", kind));
    }
    c.kind = *case_kind;
    c.file = require_string(table, "file", file, where);
    if (const toml::node* mounting = table.get("mounting")) {
      const auto label = mounting->value<std::string>();
      if (!label || label->empty()) {
        throw InputError(position_of(*mounting, file), fmt::format("mounting of case '{}' must be a non-empty string", c.name));
      }
      c.mounting = *label;
    }
    const toml::node& m_node = require(table, "m_ec", file, where);
    c.m_ec = read_matrix3(m_node, file, "m_ec");
    if (!frames::is_rotation(c.m_ec, kRotationTolerance)) {
      const double orth = (c.m_ec * c.m_ec.transpose() - frames::Dcm::Identity()).cwiseAbs().maxCoeff();
      throw InputError(position_of(m_node, file),
                       fmt::format("m_ec of case '{}' is not a rotation: max |M M^T - I| = {:.3g}, det = {:.9g} "
                                   "(tolerance {}); its rows must be the case axes IRA, XRA, YRA written in F_E",
                                   c.name, orth, c.m_ec.determinant(), kRotationTolerance));
    }
    if (const toml::node* placement = table.get("placement_sd_deg")) {
      const std::optional<double> deg = placement->value<double>();
      if (!deg || !std::isfinite(*deg) || *deg < 0.0 || *deg > 10.0) {
        throw InputError(position_of(*placement, file),
                         fmt::format("placement_sd_deg of case '{}' must be a number of degrees from 0 to 10", c.name));
      }
      c.placement_sd_rad = *deg * kPi / 180.0;
    }
    if (const toml::node* piece = table.get("piece_of")) {
      const auto label = piece->value<std::string>();
      if (!label || label->empty()) {
        throw InputError(position_of(*piece, file), fmt::format("piece_of of case '{}' must be a non-empty string", c.name));
      }
      c.piece_of = *label;
      // The pieces of one case are one case of the plan: the same kind, orientation and mounting.
      for (const CaseData& other : data.cases) {
        if (other.piece_of != c.piece_of) continue;
        if (other.kind != c.kind || other.mounting != c.mounting || (other.m_ec - c.m_ec).cwiseAbs().maxCoeff() > kRotationTolerance) {
          throw InputError(position_of(*piece, file),
                           fmt::format("case '{}' is a piece of '{}' but differs from its piece '{}' in kind, mounting "
                                       "or m_ec; the pieces of one case share all three",
                                       c.name, c.piece_of, other.name));
        }
      }
    }
    const std::filesystem::path csv = dir / c.file;
    if (!std::filesystem::is_regular_file(csv)) {
      throw InputError(position_of(*table.get("file"), file),
                       fmt::format("case '{}': file '{}' not found", c.name, csv.string()));
    }
    data.cases.push_back(std::move(c));
  }
  return data;
}

struct CaseRowStream::Impl {
  CaseData shape;   // the header's columns; no rows
  CaseCsv csv;
  Eigen::Index rows = 0;
  double period = 0.0;
  std::vector<std::string> phase_names;

  Impl(const std::filesystem::path& file, std::ostream& warnings) : csv(file, shape, warnings, false) {}

  /// The rows the file holds and its last time: the last chunk with a data row, parsed first.
  /// None when that chunk does not parse (the pass in order then stops at its error).
  std::optional<double> last_time() {
    CaseData block;
    for (std::size_t c = csv.chunks(); c-- > 0;) {
      try {
        csv.parse_chunk_into(c, block);
      } catch (const InputError&) {
        return std::nullopt;
      }
      if (block.size() > 0) {
        rows = csv.chunk_first_row(c) + block.size();
        return block.t[block.size() - 1];
      }
    }
    return std::nullopt;
  }

  /// One pass over the chunks in order, each block to `consume` (when set) with its labels
  /// numbered over the file. With `check`, the errors read_case_csv raises, in its order: a bad
  /// field at once, the time column's once every row has parsed.
  void pass(const BlockConsumer& consume, bool check) {
    const std::optional<double> last_t = check ? last_time() : std::nullopt;
    csv.rewind();
    phase_names.clear();
    std::optional<InputError> time_error;
    std::optional<double> previous;
    // The chunks parse a group at a time on the --jobs threads, each into a block of its own,
    // and are then taken in order: memory holds one group.
    const auto group = static_cast<std::size_t>(std::max(1, parallel::jobs()));
    std::vector<CaseData> blocks(group);
    std::vector<std::exception_ptr> errors(group);
    for (std::size_t first = 0; first < csv.chunks(); first += group) {
      const std::size_t count = std::min(group, csv.chunks() - first);
      parallel::for_each_index(static_cast<long>(count), [&](long i) {
        errors[static_cast<std::size_t>(i)] = nullptr;
        try {
          csv.parse_chunk_into(first + static_cast<std::size_t>(i), blocks[static_cast<std::size_t>(i)]);
        } catch (...) {
          errors[static_cast<std::size_t>(i)] = std::current_exception();
        }
      });
      for (std::size_t i = 0; i < count; ++i) {
        if (errors[i]) std::rethrow_exception(errors[i]);
        if (!take(first + i, blocks[i], consume, check, last_t, time_error, previous)) {
          first = csv.chunks();   // trailing blank lines: the data ended
          break;
        }
      }
      if (first + count < csv.chunks()) csv.release_before_chunk(first + count);
    }
    if (!check) return;
    if (!last_t) (void)sample_period(csv.name(), csv.time_column(), 0, 0.0, 0.0);   // no data row
    if (time_error) throw *time_error;
  }

  /// Chunk c's parsed block, in order: its labels numbered over the file, its time steps checked,
  /// then to `consume`. False when the block is empty (the data ended before it).
  bool take(std::size_t c, CaseData& block, const BlockConsumer& consume, bool check, const std::optional<double>& last_t,
            std::optional<InputError>& time_error, std::optional<double>& previous) {
    if (block.size() == 0) return false;
    const Eigen::Index first_row = csv.chunk_first_row(c);
    if (!block.phase.empty()) csv.number_phases_over_file(c, phase_names, block.phase.data(), block.size());
    if (check && c == 0 && last_t) {
      try {
        period = sample_period(csv.name(), csv.time_column(), rows, block.t[0], *last_t);
      } catch (const InputError& e) {
        time_error = e;
      }
    }
    if (check && !time_error && period > 0.0) time_error = uneven_step(csv.name(), csv.time_column(), block.t, first_row, previous, period);
    previous = block.t[block.size() - 1];
    block.phase_names = phase_names;
    block.sample_period_s = period;
    if (consume) consume(block, first_row);
    return true;
  }
};

CaseRowStream::CaseRowStream(const std::filesystem::path& file, std::ostream& warnings, const BlockConsumer& check)
    : impl_(std::make_unique<Impl>(file, warnings)) {
  impl_->pass(check, true);
}

CaseRowStream::~CaseRowStream() = default;
CaseRowStream::CaseRowStream(CaseRowStream&&) noexcept = default;
CaseRowStream& CaseRowStream::operator=(CaseRowStream&&) noexcept = default;

Eigen::Index CaseRowStream::rows() const { return impl_->rows; }
double CaseRowStream::sample_period_s() const { return impl_->period; }
const std::vector<std::string>& CaseRowStream::phase_names() const { return impl_->phase_names; }
void CaseRowStream::for_each_block(const BlockConsumer& consume) { impl_->pass(consume, false); }

std::uintmax_t csv_bytes(const Dataset& data) {
  // Each case's rows formatted up to kSampledRows, the rest taken at their mean length: the
  // shortest round-trip form varies with the digits a value needs, not with the record's length.
  constexpr Eigen::Index kSampledRows = 4096;
  double bytes = 0.0;
  std::string csv;
  for (const CaseData& c : data.cases) {
    csv = csv_header(c);
    const std::size_t header = csv.size();
    const Eigen::Index sampled = std::min(c.size(), kSampledRows);
    for (Eigen::Index k = 0; k < sampled; ++k) append_csv_row(csv, c, k);
    bytes += static_cast<double>(header);
    if (sampled > 0) bytes += static_cast<double>(csv.size() - header) * static_cast<double>(c.size()) / static_cast<double>(sampled);
  }
  return static_cast<std::uintmax_t>(std::ceil(bytes));
}

void write_dataset(const std::filesystem::path& dir, const Dataset& data) {
  std::string toml_text;
  toml_text += "sensor = " + toml_quote(to_string(data.sensor)) + "\n";
  if (!data.sensor_name.empty()) toml_text += "sensor_name = " + toml_quote(data.sensor_name) + "\n";
  if (!data.serial.empty()) toml_text += "serial = " + toml_quote(data.serial) + "\n";
  if (!data.part.empty()) toml_text += "part = " + toml_quote(data.part) + "\n";
  if (!data.unit.empty() && data.unit_axis >= 0)
    toml_text += "unit = " + toml_quote(data.unit) + "\nunit_axis = \"" + std::string(1, static_cast<char>('x' + data.unit_axis)) + "\"\n";
  toml_text += "output_unit = " + toml_quote(data.output_unit) + "\n";
  toml_text += "t_ref = " + toml_float(data.t_ref) + "\n";

  std::vector<std::string> files;
  for (const CaseData& c : data.cases) {
    const Eigen::Index n = c.size();
    const auto bad = [&](const std::string& why) {
      return InputError(fmt::format("cannot write case '{}': {}", c.name, why));
    };
    if (c.a_e.rows() != n || c.y.size() != n || (c.w_e && c.w_e->rows() != n) || (c.temp && c.temp->size() != n) ||
        (!c.phase.empty() && c.phase.size() != static_cast<std::size_t>(n))) {
      throw bad("columns differ in length");
    }
    for (const std::string& label : c.phase_names) {
      if (label.find_first_of(",\"\r\n") != std::string::npos) {
        throw bad(fmt::format("phase label '{}' holds a comma, quote or line break", label));
      }
    }
    for (std::uint16_t p : c.phase) {
      if (p >= c.phase_names.size()) throw bad("phase index beyond phase_names");
    }
    files.push_back(c.file.empty() ? c.name + ".csv" : c.file);

    toml_text += "\n[[case]]\n";
    toml_text += "name = " + toml_quote(c.name) + "\n";
    toml_text += "kind = " + toml_quote(to_string(c.kind)) + "\n";
    toml_text += "file = " + toml_quote(files.back()) + "\n";
    if (!c.mounting.empty()) toml_text += "mounting = " + toml_quote(c.mounting) + "\n";
    if (!c.piece_of.empty()) toml_text += "piece_of = " + toml_quote(c.piece_of) + "\n";
    if (c.placement_sd_rad > 0.0) toml_text += "placement_sd_deg = " + toml_float(c.placement_sd_rad * 180.0 / kPi) + "\n";
    toml_text += "m_ec = [";
    for (int r = 0; r < 3; ++r) {
      toml_text += r == 0 ? "[" : ", [";
      for (int col = 0; col < 3; ++col) toml_text += (col == 0 ? "" : ", ") + toml_float(c.m_ec(r, col));
      toml_text += "]";
    }
    toml_text += "]\n";
  }

  require_free_space(dir, toml_text.size() + csv_bytes(data), fmt::format("dataset {}", dir.string()));
  std::filesystem::create_directories(dir);
  write_file(dir / "dataset.toml", toml_text);

  for (std::size_t i = 0; i < data.cases.size(); ++i) {
    const CaseData& c = data.cases[i];
    const std::filesystem::path path = dir / files[i];
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "wb"), &std::fclose);
    if (!f) throw std::system_error(errno, std::generic_category(), "cannot open " + path.string() + " for writing");
    // Written in ~1 MB pieces: a multi-million-row case never sits in memory twice.
    std::string csv;
    csv.reserve(kWriteChunk + 1024);
    const auto flush = [&] {
      if (std::fwrite(csv.data(), 1, csv.size(), f.get()) != csv.size()) {
        throw std::system_error(errno, std::generic_category(), "cannot write " + path.string());
      }
      csv.clear();
    };
    csv = csv_header(c);
    for (Eigen::Index k = 0; k < c.size(); ++k) {
      append_csv_row(csv, c, k);
      if (csv.size() >= kWriteChunk) flush();
    }
    flush();
    if (std::fflush(f.get()) != 0) throw std::system_error(errno, std::generic_category(), "cannot write " + path.string());
  }
}

}  // namespace inertia::dataset
