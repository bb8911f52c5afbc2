// tests/sim/folder_lock_test.cc — the output folder's lock names the process that holds it now
// (sim/files/output_set.h), not only the one that took it: a process started by the taker that
// inherited its descriptor keeps the lock after the taker has ended (what forked network workers
// did after a kill -9 of ncosim; issue 40 part 7).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "config/config.h"
#include "sim/files/output_set.h"

namespace ncosim::sim {
namespace {

namespace fs = std::filesystem;

TEST(FolderLock, NamesTheLiveHolderWhenTheTakerHasEnded) {
  const fs::path parent =
      fs::temp_directory_path() / ("ncosim_folder_lock_" + std::to_string(::getpid()));
  fs::remove_all(parent);
  const fs::path dir = parent / "out";
  int holder[2], release[2];
  ASSERT_EQ(::pipe(holder), 0);
  ASSERT_EQ(::pipe(release), 0);
  // The taker: takes the lock (writing its PID), starts a process that inherits the descriptor,
  // tells its PID and ends at once, leaving the lock to it.
  const pid_t taker = ::fork();
  ASSERT_GE(taker, 0);
  if (taker == 0) {
    OutputFolderLock lock(dir.string());
    const pid_t heir = ::fork();
    if (heir == 0) {
      char c = 0;
      ::close(holder[1]);
      ::close(release[1]);                            // else its own copy would keep the pipe open
      if (::read(release[0], &c, 1) < 0) ::_exit(1);  // until the test is done (or has ended)
      ::_exit(0);
    }
    if (::write(holder[1], &heir, sizeof heir) != sizeof heir) ::_exit(1);
    ::_exit(0);
  }
  ::close(holder[1]);
  ::close(release[0]);
  pid_t heir = -1;
  ASSERT_EQ(::read(holder[0], &heir, sizeof heir), static_cast<ssize_t>(sizeof heir));
  int status = 0;
  ASSERT_EQ(::waitpid(taker, &status, 0), taker);
  std::string message;
  try {
    OutputFolderLock second(dir.string());
    ADD_FAILURE() << "the lock was free although PID " << heir << " holds it";
  } catch (const config::ScenarioError& e) {
    message = e.what();
  }
  // The holder is named, and the taker only as the one that took it.
  EXPECT_NE(message.find("(PID " + std::to_string(heir) + ","), std::string::npos) << message;
  EXPECT_NE(message.find("the lock PID " + std::to_string(taker) + " took before it ended"),
            std::string::npos)
      << message;
  EXPECT_EQ(message.find("(PID " + std::to_string(taker) + ";"), std::string::npos) << message;
  ::close(release[1]);  // the heir ends
  ::close(holder[0]);
  for (int i = 0; i < 100; ++i) {  // it is not this process's child: wait for its end by its lock
    try {
      OutputFolderLock mine(dir.string());
      break;
    } catch (const config::ScenarioError&) {
      ::usleep(20'000);
    }
  }
  fs::remove_all(parent);
}

}  // namespace
}  // namespace ncosim::sim
