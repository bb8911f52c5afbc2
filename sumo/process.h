// sumo/process.h — child processes and files shared by the recording (recording.cc) and the live
// workers (live.cc); internal to sumo/.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ncosim::sumo {

// The whole content of a file ("" when it cannot be read).
std::string read_file(const std::filesystem::path& p);

// "S.mmm" for a duration in milliseconds.
std::string ms_to_seconds(std::int64_t ms);

// Waits for a child (retrying on EINTR); its status.
int wait_for(pid_t pid);
// "exit status N", "killed by signal N" or "stopped".
std::string exit_text(int status);

// A child process: stdin and stdout /dev/null (nothing from SUMO on our stdout), stderr to
// err_path, and `fd3` (when >= 0) as its file descriptor 3. envp: nullptr for ours.
pid_t spawn(const std::string& exe, std::vector<std::string> argv, char* const* envp,
            const std::string& err_path, int fd3 = -1);

// A number unique within this process, for temporary file names.
int next_temp_serial();

}  // namespace ncosim::sumo
