#include "analyzer/report/gnuplot.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <system_error>

namespace inertia::report {
namespace {

/// `text` as one word of a POSIX shell command: single-quoted, each ' closed, escaped and reopened.
std::string shell_quoted(const std::string& text) {
  std::string out = "'";
  for (char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace

bool run_gnuplot(const std::filesystem::path& script) {
  const std::string command = "gnuplot " + shell_quoted(script.string()) + " >/dev/null 2>&1";
  return std::system(command.c_str()) == 0;   // NOLINT(cert-env33-c): gnuplot is the plotting tool we chose
}

std::string gnuplot_quoted(std::string_view text) {
  // In a single-quoted gnuplot string, '' stands for one quote and nothing else is special.
  std::string out = "'";
  for (char c : text) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

std::optional<std::string> gnuplot_svg(const std::string& script_body, const std::filesystem::path& work_dir, SvgSize size) {
  const std::filesystem::path script = work_dir / "plot.gp";
  const std::filesystem::path svg = work_dir / "plot.svg";
  std::error_code ignored;
  std::filesystem::remove(svg, ignored);   // a drawing left by an earlier script is not this one's
  {
    std::ofstream gp(script);
    gp << fmt::format("set terminal svg size {},{} dynamic enhanced font 'sans,10'\nset output {}\n", size.width, size.height,
                      gnuplot_quoted(svg.string()));
    gp << script_body << "\nunset output\n";
    if (!gp) return std::nullopt;
  }
  if (!run_gnuplot(script)) return std::nullopt;
  std::ifstream in(svg);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  const std::string drawn = text.str();
  const std::size_t begin = drawn.find("<svg");
  const std::size_t end = drawn.rfind("</svg>");
  if (begin == std::string::npos || end == std::string::npos || end < begin) return std::nullopt;
  return drawn.substr(begin, end + std::string_view("</svg>").size() - begin) + "\n";
}

std::string svg_with_prefixed_ids(std::string_view svg, std::string_view prefix) {
  std::string out;
  out.reserve(svg.size() + svg.size() / 20);
  for (char c : svg) {
    out += c;
    const std::string_view done(out);
    const bool id_value = (done.ends_with("id=\"") || done.ends_with("id='")) && done.size() > 4 &&
                          std::isspace(static_cast<unsigned char>(done[done.size() - 5])) != 0;
    const bool reference = done.ends_with("href=\"#") || done.ends_with("href='#") || done.ends_with("url(#");
    if (id_value || reference) out += prefix;
  }
  return out;
}

ScratchDirectory::ScratchDirectory(std::string_view stem) {
  const std::filesystem::path base = std::filesystem::temp_directory_path();
  std::random_device entropy;
  std::mt19937_64 names((static_cast<std::uint64_t>(entropy()) << 32U) ^ entropy());
  // create_directory is false when the name exists: another process's, never shared.
  for (int attempt = 0; attempt < 100; ++attempt) {
    std::filesystem::path candidate = base / fmt::format("{}-{:016x}", stem, names());
    if (std::filesystem::create_directory(candidate)) {
      path_ = std::move(candidate);
      return;
    }
  }
  throw std::filesystem::filesystem_error("no fresh scratch directory", base, std::make_error_code(std::errc::file_exists));
}

ScratchDirectory::~ScratchDirectory() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

}  // namespace inertia::report
