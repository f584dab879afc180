#pragma once
// An output folder that appears whole or not at all. A run writes into a staging folder beside its
// target (TARGET.incomplete-<pid>), and commit() puts it in the target's place: one rename, or one
// atomic exchange with the previous run's folder, which is then removed. So a run stopped at any
// instant (SIGINT, SIGKILL, a crash, an exception) never leaves TARGET half written: TARGET is the
// previous complete output or absent, and what the stopped run wrote is in a folder whose name
// says it is incomplete. The next run into TARGET removes such folders whose process is gone.
//
// Replacing a folder deletes what was in it, so a target is taken only when it is absent, empty,
// or an earlier output of inertia (it holds the marker file .inertia-output); any other folder is
// refused before work starts, so that `--out .` cannot delete a user's files.
#include <filesystem>
#include <string>
#include <string_view>

namespace inertia {

class OutputFolder {
 public:
  /// The marker file commit() writes into every output folder.
  static constexpr const char* kMarker = ".inertia-output";

  /// Checks that `target` may be replaced (InputError otherwise), removes the staging folders of
  /// earlier runs into it whose process has ended, and creates this run's staging folder. `verb`
  /// names the writer in the marker.
  OutputFolder(std::filesystem::path target, std::string verb);
  /// Removes the staging folder of a run that did not commit.
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  /// Where the run writes, until commit().
  [[nodiscard]] const std::filesystem::path& path() const { return staging_; }
  [[nodiscard]] const std::filesystem::path& target() const { return target_; }
  /// `file`, a path inside path(), as it is named once committed (for messages and records).
  [[nodiscard]] std::filesystem::path final_path(const std::filesystem::path& file) const;

  /// Writes the marker and puts the staging folder in the target's place.
  void commit();

 private:
  std::filesystem::path target_, staging_;
  std::string verb_;
  bool committed_ = false;
};

}  // namespace inertia
