#include "output_dir.hpp"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include "hpcm/types.hpp"

namespace fs = std::filesystem;

namespace hpcm::cli {

namespace {

constexpr std::size_t kNameMax = 255;  // bytes in one file name (Linux filesystems)

bool has_marker(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / kOutputMarker, ec);
}

bool is_empty_dir(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && fs::directory_iterator(dir, ec) == fs::directory_iterator();
}

/// A process's start time (clock ticks after boot, /proc/PID/stat field 22); 0 when unknown.
/// With the pid it names one process: a pid reused by another program has another start time.
unsigned long long process_start(long pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::size_t paren = stat.rfind(')');  // the command name may hold spaces and ')'
  if (paren == std::string::npos) return 0;
  std::istringstream rest(stat.substr(paren + 1));
  std::string field;
  for (int i = 3; i <= 22 && rest >> field; ++i)
    if (i == 22) return std::strtoull(field.c_str(), nullptr, 10);
  return 0;
}

/// What a marker says: who wrote the folder and, for a finished run, every entry it wrote.
struct Marker {
  long pid = 0;
  unsigned long long start = 0;
  bool lists_entries = false;
  std::set<std::string> entries;  ///< relative paths, folders included
};

Marker read_marker(const fs::path& dir) {
  std::ifstream f(dir / kOutputMarker);
  Marker m;
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("pid ", 0) == 0) {
      std::istringstream s(line.substr(4));
      std::string word;
      s >> m.pid >> word >> m.start;
    } else if (line.rfind("entries ", 0) == 0) {
      m.lists_entries = true;
    } else if (line.rfind("entry ", 0) == 0) {
      m.entries.insert(line.substr(6));
    }
  }
  return m;
}

/// Every entry below `dir` (files, links, folders) as relative paths, the marker left out.
std::vector<std::string> entries_below(const fs::path& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string rel = it->path().lexically_relative(dir).string();
    if (rel != kOutputMarker) out.push_back(rel);
  }
  if (ec) throw Error(dir.string() + ": cannot list the folder (" + ec.message() + ")");
  return out;
}

/// Entries of an earlier output folder that its marker does not list: files somebody added.
std::vector<std::string> foreign_entries(const fs::path& dir, const Marker& m) {
  std::vector<std::string> foreign;
  for (const std::string& e : entries_below(dir))
    if (!m.entries.count(e)) foreign.push_back(e);
  return foreign;
}

std::string list_some(const std::vector<std::string>& names) {
  std::string s;
  const std::size_t shown = std::min<std::size_t>(names.size(), 5);
  for (std::size_t i = 0; i < shown; ++i) s += (i ? ", " : "") + names[i];
  if (names.size() > shown) s += " and " + std::to_string(names.size() - shown) + " more";
  return s;
}

void write_marker(const fs::path& dir, const std::string& what, const std::vector<std::string>& entries,
                  bool list_entries) {
  std::ofstream f(dir / kOutputMarker);
  f << "hpcm output folder (" << what << ")\npid " << ::getpid() << " start " << process_start(::getpid()) << "\n";
  if (list_entries) {
    f << "entries " << entries.size() << "\n";
    for (const std::string& e : entries) f << "entry " << e << "\n";
  }
  f.close();
  if (!f) throw Error((dir / kOutputMarker).string() + ": write failed (disk full?)");
}

/// DIR.incomplete, or for a name too long for that a shortened name with a hash of the full one.
fs::path staging_for(const fs::path& d, const std::string& suffix) {
  const std::string name = d.filename().string();
  if (name.size() + suffix.size() <= kNameMax) return d.parent_path() / (name + suffix);
  char hash[24];
  std::snprintf(hash, sizeof hash, "~%016zx", std::hash<std::string>{}(name));
  const std::size_t keep = kNameMax - suffix.size() - std::strlen(hash);
  return d.parent_path() / (name.substr(0, keep) + hash + suffix);
}

/// True when `child` lies strictly inside `parent` (both absolute and normal).
bool strictly_inside(const fs::path& child, const fs::path& parent) {
  const fs::path rel = child.lexically_relative(parent);
  return !rel.empty() && rel != "." && *rel.begin() != "..";
}

/// A path made comparable with another: absolute, links of its existing part resolved, normal.
fs::path comparable(const std::string& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(fs::absolute(p), ec);
  if (ec) c = fs::absolute(p);
  c = c.lexically_normal();
  if (c.filename().empty()) c = c.parent_path();
  return c;
}

}  // namespace

StagedDir::StagedDir(const std::string& dir, const std::string& option) : dir_(dir), option_(option) {
  if (dir_.empty()) throw Error(option_ + " must name a folder");
  fs::path d = fs::path(dir_);
  if (d.filename().empty()) d = d.parent_path();  // "out/" -> "out"
  if (d.empty() || d.filename() == "." || d.filename() == "..")
    throw Error(option_ + " " + dir_ + ": name a new or earlier output folder, not '.' or '..'");
  shown_ = d.string();
  const std::string where = option_ + " " + shown_;
  if (d.string().find('\n') != std::string::npos) throw Error(option_ + ": a folder name with a line break is not accepted");
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(d, ec);
  if (fs::is_symlink(st)) {
    // Replace the folder the link points to and keep the link: staging happens beside the target.
    if (!fs::is_directory(fs::status(d, ec)))
      throw Error(where + ": is a symbolic link to something that is not a folder");
    d = fs::canonical(d, ec);
    if (ec) throw Error(where + ": cannot resolve the symbolic link (" + ec.message() + ")");
  }
  if (fs::exists(st)) {
    if (!fs::is_directory(fs::status(d, ec))) throw Error(where + ": exists and is not a folder");
    if (!is_empty_dir(d)) {
      if (!has_marker(d))
        throw Error(where + ": the folder exists and holds files hpcm did not write (no " + kOutputMarker +
                    "); choose a new folder or empty this one");
      const Marker m = read_marker(d);
      if (!m.lists_entries)
        throw Error(where + ": an earlier output folder whose " + kOutputMarker +
                    " does not list its files (written by an older hpcm); remove it or choose a new folder");
      const std::vector<std::string> foreign = foreign_entries(d, m);
      if (!foreign.empty())
        throw Error(where + ": the earlier output folder holds files hpcm did not write (" + list_some(foreign) +
                    "); a run replaces its output folder as a whole, so move them out or choose a new folder");
    }
  }
  dir_ = d.string();
  const fs::path parent = d.has_parent_path() ? d.parent_path() : fs::path(".");
  for (fs::path p = parent; !p.empty() && !fs::exists(fs::symlink_status(p, ec)); p = p.parent_path()) {
    created_parents_.push_back(p);
    if (p == p.parent_path()) break;
  }
  try {
    fs::create_directories(parent, ec);
    if (!fs::is_directory(parent, ec)) throw Error(where + ": cannot create the parent folder " + parent.string());
    if (::access(parent.c_str(), W_OK | X_OK) != 0)
      throw Error(where + ": cannot write into " + parent.string() + " (" + std::strerror(errno) + ")");

    const fs::path staging = staging_for(d, ".incomplete");
    if (fs::exists(fs::symlink_status(staging, ec))) {
      if (!fs::is_directory(fs::symlink_status(staging, ec)) || !has_marker(staging))
        throw Error(where + ": " + staging.string() + " is in the way (hpcm stages its output there); remove or rename it");
      const Marker m = read_marker(staging);
      const bool alive = m.pid > 0 && m.pid != ::getpid() && ::kill(static_cast<pid_t>(m.pid), 0) == 0;
      if (alive && m.start != 0 && process_start(m.pid) == m.start)
        throw Error(where + ": another hpcm (process " + std::to_string(m.pid) + ") is writing into " + staging.string());
      fs::remove_all(staging, ec);  // a killed or failed earlier run's partial results
      if (ec) throw Error(where + ": cannot remove the earlier partial output " + staging.string() + ": " + ec.message());
    }
    if (!fs::create_directory(staging, ec) || ec)
      throw Error(where + ": cannot create " + staging.string() + " (" + ec.message() + ")");
    staging_ = staging.string();
    write_marker(staging, "in progress; renamed to " + d.filename().string() + " when the run finishes", {}, false);
  } catch (...) {
    if (!staging_.empty()) fs::remove_all(staging_, ec);
    for (const fs::path& p : created_parents_) fs::remove(p, ec);  // only if still empty
    throw;
  }
}

StagedDir::~StagedDir() {
  if (committed_ || keep_ || staging_.empty()) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
  for (const fs::path& p : created_parents_) fs::remove(p, ec);  // only removes a folder still empty
}

void StagedDir::commit() {
  write_marker(staging_, "finished run", entries_below(staging_), true);
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(dir_, ec))) {
    fs::rename(staging_, dir_, ec);
    if (ec) throw Error(option_ + " " + shown_ + ": cannot rename " + staging_ + " into place: " + ec.message());
    committed_ = true;
    return;
  }
  // Checked again now: somebody may have put files into the earlier output during the run.
  if (!is_empty_dir(dir_)) {
    const std::vector<std::string> foreign = has_marker(dir_) ? foreign_entries(dir_, read_marker(dir_))
                                                              : entries_below(dir_);
    if (!foreign.empty()) {
      keep_ = true;
      throw Error(option_ + " " + shown_ + ": files were added to the earlier output during the run (" +
                  list_some(foreign) + "); it was left as it is, and this run's results are in " + staging_);
    }
  }
  // Swap the finished run with the earlier output in one step, then delete the earlier one.
  if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) != 0) {
    // Filesystems without RENAME_EXCHANGE: move the old folder aside first.
    const fs::path aside = staging_for(dir_, ".replaced");
    fs::remove_all(aside, ec);
    fs::rename(dir_, aside, ec);
    if (ec) throw Error(option_ + " " + shown_ + ": cannot move the earlier output aside: " + ec.message());
    fs::rename(staging_, dir_, ec);
    if (ec) throw Error(option_ + " " + shown_ + ": cannot rename " + staging_ + " into place: " + ec.message());
    fs::remove_all(aside, ec);
  } else {
    fs::remove_all(staging_, ec);  // now holds the earlier output
  }
  committed_ = true;
}

RunOutputs::RunOutputs(const std::string& out, const std::string& export_dir) {
  if (export_dir.empty()) {
    outer_.emplace(out, "--out");
    out_path_ = outer_->path();
    out_shown_ = outer_->final_path();
    return;
  }
  const fs::path o = comparable(out), e = comparable(export_dir);
  // A folder inside the other is written inside the other's staging folder.
  auto nest = [](StagedDir& outer, const fs::path& outer_at, const fs::path& inner_at, const std::string& option) {
    const fs::path inner = fs::path(outer.path()) / inner_at.lexically_relative(outer_at);
    std::error_code ec;
    fs::create_directories(inner, ec);
    if (ec) throw Error(option + ": cannot create " + inner.string() + " (" + ec.message() + ")");
    return inner.string();
  };
  if (o == e) {
    outer_.emplace(out, "--out");
    out_path_ = export_path_ = outer_->path();
  } else if (strictly_inside(e, o)) {
    outer_.emplace(out, "--out");
    out_path_ = outer_->path();
    export_path_ = nest(*outer_, o, e, "--export");
  } else if (strictly_inside(o, e)) {
    outer_.emplace(export_dir, "--export");
    export_path_ = outer_->path();
    out_path_ = nest(*outer_, e, o, "--out");
  } else {
    // Apart: neither may lie in the other's staging folder, which the other's commit removes.
    const fs::path o_staging = staging_for(o, ".incomplete"), e_staging = staging_for(e, ".incomplete");
    if (e == o_staging || strictly_inside(e, o_staging) || o == e_staging || strictly_inside(o, e_staging))
      throw Error("--out " + out + " and --export " + export_dir +
                  ": one lies in the other's staging folder (NAME.incomplete); choose other folders");
    outer_.emplace(out, "--out");
    apart_.emplace(export_dir, "--export");
    out_path_ = outer_->path();
    export_path_ = apart_->path();
  }
  const bool export_outer = strictly_inside(o, e);
  out_shown_ = export_outer ? fs::path(out).lexically_normal().string() : outer_->final_path();
  export_shown_ = apart_ ? apart_->final_path() : export_outer ? outer_->final_path() : fs::path(export_dir).lexically_normal().string();
  if (!out_shown_.empty() && out_shown_.back() == '/') out_shown_.pop_back();
  if (!export_shown_.empty() && export_shown_.back() == '/') export_shown_.pop_back();
}

void RunOutputs::keep_on_failure() {
  outer_->keep_on_failure();
  if (apart_) apart_->keep_on_failure();
}

void RunOutputs::commit() {
  if (apart_) apart_->commit();
  outer_->commit();
}

}  // namespace hpcm::cli
