#pragma once
// Starting helper programs without a shell: the arguments go to the program as a vector, so no
// character in a path (quotes, ';', '$', spaces) can ever be interpreted as a command.
#include <string>
#include <vector>

namespace hpcm::cli {

struct SpawnResult {
  bool exited = false;   ///< false: killed by a signal
  int status = 0;        ///< exit status, or the signal number when !exited
};

/// Runs argv[0] (an absolute path; no PATH search, no shell) with the given arguments and waits
/// for it. Its stdout is discarded when quiet_stdout; stderr is inherited. Throws hpcm::Error
/// when the program cannot be started.
SpawnResult run_program(const std::vector<std::string>& argv, bool quiet_stdout);

/// "prog 'arg with space' ..." for messages only (never executed).
std::string describe_command(const std::vector<std::string>& argv);

}  // namespace hpcm::cli
