// tests/cli/spawn_ncosim.h — starts the ncosim binary under test in the background (stdout and
// stderr to a log file), for the tests that signal or kill a running campaign.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <unistd.h>

#include <string>
#include <vector>

extern char** environ;

namespace ncosim::testing {

// Starts NCOSIM_BINARY with `args`; returns its pid, or -1 when it cannot be started.
inline pid_t spawn_ncosim(const std::vector<std::string>& args, const std::string& log) {
  const std::string binary = NCOSIM_BINARY;
  std::vector<std::string> all{binary};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, binary.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

}  // namespace ncosim::testing
