// sim/cmd/manifest.cc — see sim/cmd/manifest.h.
#include "sim/cmd/manifest.h"

#include <ctime>

#include "ncosim_version.h"

namespace ncosim::sim {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

nlohmann::json campaign_manifest(const LoadedScenario& loaded, const std::string& command_line,
                                 int threads, double wall_seconds) {
  const Scenario& sc = *loaded.cases.front().scenario;
  nlohmann::json j;
  j["scenario"] = loaded.file;
  j["title"] = sc.title;
  j["scenario_hash"] = loaded.hash;
  j["scenario_text_hash"] =
      loaded.text_hash;  // without --runs/--periods/--seed: what `compare` matches
  j["overrides"] = loaded.overrides;
  j["seed"] = sc.run.seed;
  j["runs"] = sc.run.runs;
  j["periods"] = sc.run.periods;
  j["warmup"] = sc.run.warmup;
  j["cases"] = loaded.cases.size();
  j["command_line"] = command_line;
  j["ncosim_version"] = NCOSIM_VERSION;
  j["git_commit"] = NCOSIM_GIT_COMMIT;
  j["date"] = utc_now();
  j["threads"] = threads;
  j["wall_seconds"] = wall_seconds;
  j["recentred"] = sc.recentre;
  return j;
}

}  // namespace ncosim::sim
