#pragma once
// gnuplot, the reports' plotting tool: a script run to the files it names (the reports' PNGs), or
// a script rendered to SVG text for a page that inlines its plots (the parameter sheet).
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace inertia::report {

/// Runs gnuplot on `script` in the script's folder (so that a script names its data files and
/// outputs relative to itself, and runs again as `gnuplot NAME.gp` there), its output discarded.
/// False when gnuplot is not installed or the script fails.
bool run_gnuplot(const std::filesystem::path& script);

/// run_gnuplot on each of `scripts`, one gnuplot process each, all side by side: a report's
/// plots take the time of the slowest, not of all. Element i says whether script i drew.
std::vector<bool> run_gnuplot_all(std::span<const std::filesystem::path> scripts);

/// gnuplot on each of `scripts` (as run_gnuplot), started side by side when constructed and waited
/// for in wait(): the caller writes the rest of its output while they draw. The destructor waits
/// for runs not waited for, so that no child outlives the folder it draws into.
class GnuplotRuns {
 public:
  explicit GnuplotRuns(std::span<const std::filesystem::path> scripts);
  ~GnuplotRuns();
  GnuplotRuns(const GnuplotRuns&) = delete;
  GnuplotRuns& operator=(const GnuplotRuns&) = delete;

  /// Element i says whether script i drew; the runs' children are reaped.
  std::vector<bool> wait();

 private:
  std::vector<int> children_;   // pids; -1 when a script's gnuplot could not start
};

/// The `set terminal` line (newline included) of every PNG a report draws, `width` x `height`
/// pixels: gnuplot's libgd terminal. The reports' time traces are thousands of noisy segments a
/// plot, which the cairo terminal antialiases at three times the cost for no visible gain
/// (docs/validation.md, "The reports' PNGs").
std::string png_terminal(int width, int height);

/// `text` as a gnuplot string literal (single-quoted): a data file's path, a label.
std::string gnuplot_quoted(std::string_view text);

struct SvgSize {
  int width = 720, height = 420;   // the viewBox, in pixels at 100 %
};

/// The SVG gnuplot draws from `script_body` (the plot commands, data files named by absolute path
/// or relative to work_dir, where gnuplot runs): the body runs after `set terminal svg size W,H
/// dynamic enhanced font 'sans,10'` and `set output`, as work_dir/plot.gp, drawing to
/// work_dir/plot.svg (both overwritten). The text starts at its <svg> element, without the XML
/// prolog or DOCTYPE, so that it inlines in an HTML page. nullopt when gnuplot is not installed,
/// the script fails, or it draws nothing.
std::optional<std::string> gnuplot_svg(const std::string& script_body, const std::filesystem::path& work_dir, SvgSize size = {});

/// `svg` with every id it defines, and every reference to one (href="#...", url(#...)), prefixed
/// by `prefix`: gnuplot names its markers and groups alike in every plot, and one HTML page must
/// not hold an id twice.
std::string svg_with_prefixed_ids(std::string_view svg, std::string_view prefix);

/// A fresh directory under std::filesystem::temp_directory_path(), removed with its content when
/// this goes out of scope: where a page's plot data and scripts live while gnuplot reads them.
class ScratchDirectory {
 public:
  /// Throws std::filesystem::filesystem_error when no directory can be created.
  explicit ScratchDirectory(std::string_view stem);
  ~ScratchDirectory();
  ScratchDirectory(const ScratchDirectory&) = delete;
  ScratchDirectory& operator=(const ScratchDirectory&) = delete;

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace inertia::report
