// config/input_files.h — the external files a scenario reads (trace files, SUMO net, route and
// configuration files, ...), recorded while it loads, with a hash of each one's content.
//
// A campaign's identity is its scenario text and options *and* the content of every file that
// text names: two shards run against different contents of one trace file are different
// campaigns. Readers that open a file named by a scenario call note_input_file(); the scenario
// loader (sim/scenario/scenario.cc) holds an InputFileRecorder for the duration of a load and keeps
// what it recorded in LoadedScenario::inputs. Without a recorder the call does nothing.
#pragma once

#include <map>
#include <string>

namespace ncosim::config {

// Path relative to the scenario's folder (whatever the working directory or the folder's own
// location: shards run from elsewhere and `export` from the stored absolute path agree) ->
// content hash (16 hex digits, FNV-1a 64 of the bytes).
using InputFiles = std::map<std::string, std::string>;

// Records into `files` every note_input_file() of this thread while alive (nests: the innermost
// recorder receives them).
class InputFileRecorder {
 public:
  // `scenario_dir`: the folder of the scenario file (relative to the working directory or
  // absolute; "" = the working directory), against which the recorded keys are made relative.
  InputFileRecorder(InputFiles& files, const std::string& scenario_dir);
  ~InputFileRecorder();
  InputFileRecorder(const InputFileRecorder&) = delete;
  InputFileRecorder& operator=(const InputFileRecorder&) = delete;

 private:
  InputFiles* previous_;
  std::string previous_dir_;
};

// Records `path` (as the reader opened it; its content read now) with the recorder of this
// thread, if any, under its path relative to the scenario's folder. A file that cannot be read is
// recorded as "unreadable" (its reader reports the error).
void note_input_file(const std::string& path);

// The content hash used for input files: FNV-1a 64 of `bytes`, 16 lower-case hex digits.
std::string content_hash(const std::string& bytes);

// The hash of the file at `path` now: content_hash of its bytes, "missing" when it does not exist,
// "unreadable" when it cannot be read (a folder, a FIFO, no permission).
std::string file_content_hash(const std::string& path);

}  // namespace ncosim::config
