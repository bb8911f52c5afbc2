// sim/files/output_set.h — the atomic output set and the output-folder lock.
//
// A result set appears all together or not at all: write_output_set() writes every file into a
// temporary sibling folder (PARENT/.NAME.new.PID), fsyncs each file and the folder, carries over
// (hard links) every entry of the live folder that the new set neither writes nor declares stale
// (e.g. a run store runs.sqlite kept by another component), then swaps the two folders in one
// step (Linux renameat2 RENAME_EXCHANGE), fsyncs the parent and removes the previous folder. A
// reader, or a kill at any point, sees either the previous set or the complete new one.
//
// A lock (flock on the sibling file PARENT/.NAME.lock, holding the owner's PID) excludes a second
// writer to the same folder: acquiring it while another process holds it throws ScenarioError
// (exit 2) naming the holder's PID. The lock is per process and re-entrant; hold an
// OutputFolderLock for the whole command (run, design, codesign) and write_output_set() takes it
// (again) for the write. Leftover temporaries of killed writers (.NAME.new.*, .NAME.old.*, and
// .FILE.tmpPID files of older versions) are removed by the next writer, which reports them.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace ncosim::sim {

// Holds the lock of output folder `dir` (its parent is created if needed) while alive. Taking it
// first restores a previous set that an interrupted fallback swap left aside (before anything
// can create an empty folder in its place), so take it before creating the folder.
class OutputFolderLock {
 public:
  explicit OutputFolderLock(const std::string& dir);
  ~OutputFolderLock();
  OutputFolderLock(const OutputFolderLock&) = delete;
  OutputFolderLock& operator=(const OutputFolderLock&) = delete;

 private:
  std::string key_;
};

// A file of the new set that is not written from memory: `make(path)` creates it at `path` (for
// the run store: a hard link to the finished store built beside the folder, or a copy).
struct InstalledFile {
  std::string name;
  std::function<void(const std::filesystem::path&)> make;
};

// Writes `files` (name, content) and `installs` as the new result set of `dir`; entries named in
// `stale` that the set does not write are dropped (a name ending in '*' drops every entry that
// starts with what precedes it, e.g. "plot_*"), every other existing entry is carried over.
// Throws std::runtime_error on an I/O failure (the previous set stays, temporaries are removed)
// and ScenarioError when another process holds the folder's lock. Returns the number of leftover
// temporaries of interrupted writers that were removed (also reported on stderr).
int write_output_set(const std::string& dir,
                     const std::vector<std::pair<std::string, std::string>>& files,
                     const std::vector<std::string>& stale,
                     const std::vector<InstalledFile>& installs = {});

// The folder that holds the result set of `dir` once symlinks are resolved (absolute).
std::string output_set_folder(const std::string& dir);

// Test hooks (environment): NCOSIM_TEST_NO_EXCHANGE=1 takes the fallback path (move aside,
// rename in); NCOSIM_TEST_OUTPUT_STEPS=1 prints each step of the write sequence
// on stderr ("ncosim: output step K: WHAT"); NCOSIM_TEST_KILL_AT=K sends SIGKILL to the process
// just before step K (1-based), so tests can kill at every rename and fsync.

// Writes every (name, content) as the new result set of `dir`, atomically as a whole (a sibling
// folder fsynced and swapped in; see write_output_set above). Creates `dir` if needed. Throws
// std::runtime_error on failure (the previous set stays) and ScenarioError when another process
// holds the folder's lock. `stale` names earlier outputs to drop when they are not part of this
// set (e.g. a trajectory.csv of an earlier --trace run); every other existing entry is carried
// over, so the folder never mixes two result sets.
void write_files_atomically(const std::string& dir,
                            const std::vector<std::pair<std::string, std::string>>& files,
                            const std::vector<std::string>& stale = {});

// For a command that reads the result set in `dir` (export, merge, plot, report): when a write
// into it was interrupted after moving the previous set aside (the fallback swap) and the folder
// is missing, restores that set under the folder's lock, as the next writer would, and says so.
// Does nothing otherwise (a missing folder stays missing for the reader's own message).
void restore_interrupted_write(const std::string& dir);

// Creates `dir` and checks that its parent is writable (the set is swapped in from a sibling),
// before any work: throws std::runtime_error (ScenarioError for an empty folder name, the root or
// the current directory).
void prepare_output_dir(const std::string& dir);

}  // namespace ncosim::sim
