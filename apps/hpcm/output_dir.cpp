#include "output_dir.hpp"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "hpcm/types.hpp"

namespace fs = std::filesystem;

namespace hpcm::cli {

namespace {

bool has_marker(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / kOutputMarker, ec);
}

/// Process id written in a staging folder's marker (0 when none).
long marker_pid(const fs::path& dir) {
  std::ifstream f(dir / kOutputMarker);
  std::string word;
  long pid = 0;
  while (f >> word)
    if (word == "pid") f >> pid;
  return pid;
}

bool is_empty_dir(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && fs::directory_iterator(dir, ec) == fs::directory_iterator();
}

void write_marker(const fs::path& dir, const std::string& what) {
  std::ofstream f(dir / kOutputMarker);
  f << "hpcm output folder (" << what << ")\npid " << ::getpid() << "\n";
  if (!f) throw Error(dir.string() + ": cannot write files here");
}

}  // namespace

StagedDir::StagedDir(const std::string& dir, const std::string& option) : dir_(dir), option_(option) {
  if (dir_.empty()) throw Error(option_ + " must name a folder");
  fs::path d = fs::path(dir_);
  if (d.filename().empty()) d = d.parent_path();  // "out/" -> "out"
  if (d.empty() || d.filename() == "." || d.filename() == "..")
    throw Error(option_ + " " + dir_ + ": name a new or earlier output folder, not '.' or '..'");
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(d, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(fs::status(d, ec)))
      throw Error(option_ + " " + dir_ + ": exists and is not a folder");
    if (!is_empty_dir(d) && !has_marker(d))
      throw Error(option_ + " " + dir_ + ": the folder exists and holds files hpcm did not write (no " + kOutputMarker +
                  "); choose a new folder or empty this one");
  }
  const fs::path parent = d.has_parent_path() ? d.parent_path() : fs::path(".");
  fs::create_directories(parent, ec);
  if (!fs::is_directory(parent, ec))
    throw Error(option_ + " " + dir_ + ": cannot create the parent folder " + parent.string());
  if (::access(parent.c_str(), W_OK | X_OK) != 0)
    throw Error(option_ + " " + dir_ + ": cannot write into " + parent.string() + " (" + std::strerror(errno) + ")");

  const fs::path staging = d.string() + ".incomplete";
  if (fs::exists(fs::symlink_status(staging, ec))) {
    if (!fs::is_directory(fs::symlink_status(staging, ec)) || !has_marker(staging))
      throw Error(option_ + " " + dir_ + ": " + staging.string() +
                  " is in the way (hpcm stages its output there); remove or rename it");
    const long pid = marker_pid(staging);
    if (pid > 0 && pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) == 0)
      throw Error(option_ + " " + dir_ + ": another hpcm (process " + std::to_string(pid) + ") is writing into " +
                  staging.string());
    fs::remove_all(staging, ec);  // a killed or failed earlier run's partial results
    if (ec) throw Error(option_ + " " + dir_ + ": cannot remove the earlier partial output " + staging.string() + ": " + ec.message());
  }
  if (!fs::create_directory(staging, ec) || ec)
    throw Error(option_ + " " + dir_ + ": cannot create " + staging.string() + " (" + ec.message() + ")");
  staging_ = staging.string();
  dir_ = d.string();
  write_marker(staging, "in progress; renamed to " + d.filename().string() + " when the run finishes");
}

StagedDir::~StagedDir() {
  if (committed_ || keep_ || staging_.empty()) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void StagedDir::commit() {
  write_marker(staging_, "finished run");
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(dir_, ec))) {
    fs::rename(staging_, dir_, ec);
    if (ec) throw Error(option_ + " " + dir_ + ": cannot rename " + staging_ + " into place: " + ec.message());
    committed_ = true;
    return;
  }
  // Swap the finished run with the earlier output in one step, then delete the earlier one.
  if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) != 0) {
    // Filesystems without RENAME_EXCHANGE: move the old folder aside first.
    const std::string aside = dir_ + ".replaced";
    fs::remove_all(aside, ec);
    fs::rename(dir_, aside, ec);
    if (ec) throw Error(option_ + " " + dir_ + ": cannot move the earlier output aside: " + ec.message());
    fs::rename(staging_, dir_, ec);
    if (ec) throw Error(option_ + " " + dir_ + ": cannot rename " + staging_ + " into place: " + ec.message());
    fs::remove_all(aside, ec);
  } else {
    fs::remove_all(staging_, ec);  // now holds the earlier output
  }
  committed_ = true;
}

}  // namespace hpcm::cli
