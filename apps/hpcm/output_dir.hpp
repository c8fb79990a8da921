#pragma once
// Output folders of hpcm run / experiment / bench: a run writes into a fresh staging folder
// beside the destination (DIR.incomplete) and only a finished run is renamed into place. So a
// failed or killed run never mixes its files with an earlier run's, and the destination
// problems (not writable, a file in the way, a folder of someone else's files) are found
// before any simulation starts.
//
// A finished folder's marker (.hpcm-output) lists every file the run wrote. An earlier output
// folder is replaced only when it holds nothing else: a file a user added is never deleted.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace hpcm::cli {

class StagedDir {
 public:
  /// Checks DIR (named `option` in messages) and creates DIR.incomplete. DIR may be missing
  /// (its parents are created), empty, or an earlier hpcm output folder holding only the files
  /// its marker lists (which the finished run replaces); anything else is an error. A DIR that
  /// is a symbolic link to a folder stays a link: the run replaces the folder it points to.
  StagedDir(const std::string& dir, const std::string& option);
  StagedDir(const StagedDir&) = delete;
  StagedDir& operator=(const StagedDir&) = delete;
  /// Not committed: removes the staging folder unless keep_on_failure() was called, and the
  /// parent folders this object created when they are still empty.
  ~StagedDir();

  /// Where this run writes (the staging folder).
  const std::string& path() const { return staging_; }
  /// The destination as the user gave it.
  const std::string& final_path() const { return shown_; }
  /// From now on a failed or killed run leaves DIR.incomplete behind (its partial results).
  void keep_on_failure() { keep_ = true; }
  bool keeps_on_failure() const { return keep_; }
  /// Puts the staging folder in place of DIR (replacing an earlier hpcm output folder).
  void commit();

 private:
  std::string dir_, shown_, option_, staging_;
  std::vector<std::filesystem::path> created_parents_;  ///< deepest first
  bool keep_ = false, committed_ = false;
};

/// The output folders of `hpcm run`: --out and, optionally, --export. They may be the same
/// folder, nested either way, or apart. Only the outer one is staged; a folder inside it is
/// written inside its staging folder and comes into place with it, so committing one never
/// replaces the other.
class RunOutputs {
 public:
  /// Checks both destinations before anything is written; `export_dir` empty: no export.
  RunOutputs(const std::string& out, const std::string& export_dir);
  /// Where frames.csv goes now, and where the exports go now (empty without --export).
  const std::string& out_path() const { return out_path_; }
  const std::string& export_path() const { return export_path_; }
  /// The destinations as the user named them, for messages.
  const std::string& out_shown() const { return out_shown_; }
  const std::string& export_shown() const { return export_shown_; }
  void keep_on_failure();
  /// Puts every staged folder in place.
  void commit();

 private:
  std::optional<StagedDir> outer_, apart_;
  std::string out_path_, export_path_, out_shown_, export_shown_;
};

/// Name of the marker file hpcm leaves in each output folder it wrote.
inline constexpr const char* kOutputMarker = ".hpcm-output";

}  // namespace hpcm::cli
