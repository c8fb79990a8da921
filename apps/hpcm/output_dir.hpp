#pragma once
// Output folders of hpcm run / experiment / bench: a run writes into a fresh staging folder
// beside the destination (DIR.incomplete) and only a finished run is renamed into place. So a
// failed or killed run never mixes its files with an earlier run's, and the destination
// problems (not writable, a file in the way, a folder of someone else's files) are found
// before any simulation starts.
#include <string>

namespace hpcm::cli {

class StagedDir {
 public:
  /// Checks DIR (named `option` in messages) and creates DIR.incomplete. DIR may be missing
  /// (its parents are created), empty, or an earlier hpcm output folder (which the finished run
  /// replaces); anything else is an error.
  StagedDir(const std::string& dir, const std::string& option);
  StagedDir(const StagedDir&) = delete;
  StagedDir& operator=(const StagedDir&) = delete;
  /// Not committed: removes the staging folder unless keep_on_failure() was called.
  ~StagedDir();

  /// Where this run writes (the staging folder).
  const std::string& path() const { return staging_; }
  /// The destination as the user gave it.
  const std::string& final_path() const { return dir_; }
  /// From now on a failed or killed run leaves DIR.incomplete behind (its partial results).
  void keep_on_failure() { keep_ = true; }
  bool keeps_on_failure() const { return keep_; }
  /// Puts the staging folder in place of DIR (replacing an earlier hpcm output folder).
  void commit();

 private:
  std::string dir_, option_, staging_;
  bool keep_ = false, committed_ = false;
};

/// Name of the marker file hpcm leaves in each output folder it wrote.
inline constexpr const char* kOutputMarker = ".hpcm-output";

}  // namespace hpcm::cli
