#include "analyzer/report/gnuplot.hpp"

#include <fmt/format.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <system_error>

namespace inertia::report {
namespace {

/// Starts `gnuplot NAME` in the script's folder, its standard streams on /dev/null. The child's
/// pid, or -1 when it could not start.
pid_t spawn_gnuplot(const std::filesystem::path& script) {
  posix_spawn_file_actions_t actions;
  if (::posix_spawn_file_actions_init(&actions) != 0) return -1;
  const std::string folder = script.has_parent_path() ? script.parent_path().string() : std::string(".");
  const std::string name = script.filename().string();
  const bool prepared = ::posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0) == 0 &&
                        ::posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0) == 0 &&
                        ::posix_spawn_file_actions_adddup2(&actions, 1, 2) == 0 &&
                        ::posix_spawn_file_actions_addchdir_np(&actions, folder.c_str()) == 0;
  pid_t pid = -1;
  std::array<char*, 3> argv{const_cast<char*>("gnuplot"), const_cast<char*>(name.c_str()), nullptr};
  if (prepared && ::posix_spawnp(&pid, "gnuplot", &actions, nullptr, argv.data(), environ) != 0) pid = -1;
  ::posix_spawn_file_actions_destroy(&actions);
  return prepared ? pid : -1;
}

/// Whether the child `pid` ended with status 0.
bool exited_cleanly(pid_t pid) {
  int status = 0;
  pid_t got = -1;
  do {
    got = ::waitpid(pid, &status, 0);
  } while (got < 0 && errno == EINTR);
  return got == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

}  // namespace

bool run_gnuplot(const std::filesystem::path& script) {
  return run_gnuplot_all(std::span<const std::filesystem::path>(&script, 1)).front();
}

std::vector<bool> run_gnuplot_all(std::span<const std::filesystem::path> scripts) { return GnuplotRuns(scripts).wait(); }

GnuplotRuns::GnuplotRuns(std::span<const std::filesystem::path> scripts) {
  children_.reserve(scripts.size());
  for (const std::filesystem::path& script : scripts) children_.push_back(spawn_gnuplot(script));
}

GnuplotRuns::~GnuplotRuns() { wait(); }

std::vector<bool> GnuplotRuns::wait() {
  std::vector<bool> drawn;
  drawn.reserve(children_.size());
  for (const pid_t pid : children_) drawn.push_back(pid > 0 && exited_cleanly(pid));
  children_.clear();
  return drawn;
}

std::string png_terminal(int width, int height) { return fmt::format("set terminal png size {},{}\n", width, height); }

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
