// sim/cmd/record_link.cc — `ncosim record-link`.
#include "sim/cmd/record_link.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "config/config.h"
#include "config/toml_path.h"
#include "kernel/rng.h"
#include "kernel/time.h"
#include "models/fit.h"
#include "models/link.h"
#include "sim/analysis/output.h"
#include "sim/files/output_set.h"
#include "sim/run/run.h"

namespace ncosim::sim {

namespace {

// What a trace link reads at most (models/link.cc): a longer record could not be replayed.
constexpr std::int64_t kMaxPackets = 50'000'000;
// The design law given to network links without one while recording (every packet on time).
constexpr const char* kPlaceholderLaw = "[1.0]";

// The senders of link `l`: its sensors, in sensor order. Refuses what cannot be recorded alone.
std::vector<std::size_t> senders(const Scenario& sc, std::size_t l) {
  const auto& name = sc.links[l].name;
  for (const auto& a : sc.model.actuators) {
    if (a.spec.link == static_cast<int>(l)) {
      throw config::ScenarioError(
          fmt::format("--link: link '{}' carries an actuator's commands: only links of periodic "
                      "sensors can be recorded",
                      name));
    }
  }
  if (sc.links[l].link->independent_copies()) {
    throw config::ScenarioError(
        fmt::format("--link: link '{}' delivers independent copies (several delays per packet): a "
                    "trace holds one",
                    name));
  }
  std::vector<std::size_t> out;
  for (std::size_t s = 0; s < sc.model.sensors.size(); ++s) {
    const auto& spec = sc.model.sensors[s].spec;
    if (spec.link != static_cast<int>(l)) continue;
    if (!spec.policy->sends_every_sample()) {
      throw config::ScenarioError(
          fmt::format("--link: sensor {} on link '{}' sends by policy \"{}\" (its send times "
                      "depend on the simulation): only "
                      "sensors that send every sample can be recorded",
                      s, name, spec.policy->name()));
    }
    out.push_back(s);
  }
  if (out.empty())
    throw config::ScenarioError(fmt::format("--link: link '{}' carries no sensor's packets", name));
  return out;
}

// What a record with placeholder laws should be told: which links, and that a controller reading
// an estimator's estimate makes the plant (and the send times of send-on-delta senders) depend
// on its design.
void note_placeholders(const Scenario& sc, const std::vector<std::string>& links) {
  std::string names;
  for (const auto& n : links) names += (names.empty() ? "'" : ", '") + n + "'";
  std::cerr << fmt::format(
      "record-link: no design_pmf on network link(s) {}: the designs (which a record does not "
      "use) are made with design_pmf = {}\n",
      names, kPlaceholderLaw);
  if (sc.input.source_index >= 0) {
    std::cerr << fmt::format(
        "record-link: note: the controller reads estimator \"{}\", whose design may use that "
        "placeholder: where send times depend on the measurements, the record is of that "
        "design's loop\n",
        sc.input.source);
  }
}

// A network link's packets: their fates come from the whole run (every sender of the network
// contends), the network in a worker process of its own per run (network/worker.h), as in a
// campaign; up to `jobs` runs at a time, each on a thread of this process (no fork here: the
// workers are spawned, sim/run/network_path.h).
void record_network_runs(const Scenario& sc, std::size_t l, std::int64_t runs, int jobs,
                         RecordedTrace& out) {
  std::vector<std::vector<RecordedPacket>> done(static_cast<std::size_t>(runs));
  std::atomic<std::int64_t> next{0};
  std::atomic<bool> failed{false};
  std::mutex mutex;
  std::exception_ptr error;
  std::int64_t error_run = runs;  // the first failed run's error is the one told
  auto work = [&] {
    for (std::int64_t r = next++; r < runs && !failed; r = next++) {
      try {
        done[static_cast<std::size_t>(r)] =
            record_network_link(sc, static_cast<std::uint64_t>(r), l);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        if (r < error_run) {
          error_run = r;
          error = std::current_exception();
        }
        failed = true;
      }
    }
  };
  const auto n = static_cast<std::int64_t>(std::max(1, jobs));
  std::vector<std::thread> threads;
  for (std::int64_t t = 1; t < std::min(n, runs); ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  const std::string& name = sc.links[l].name;
  if (error) {
    try {
      std::rethrow_exception(error);
    } catch (const network::EngineFailure& e) {
      throw std::runtime_error(
          fmt::format("record-link: run {} of link '{}': {}", error_run, name, e.what()));
    }
  }
  for (std::int64_t r = 0; r < runs; ++r) {
    const auto& packets = done[static_cast<std::size_t>(r)];
    if (packets.size() != static_cast<std::size_t>(out.per_run)) {
      throw std::runtime_error(
          fmt::format("record-link: run {} of link '{}' sent {} packets, "
                      "expected {}",
                      r, name, packets.size(), out.per_run));
    }
    for (const RecordedPacket& p : packets) out.delays.push_back(p.delay);
  }
}

}  // namespace

int record_jobs(int threads) {
  return threads > 0 ? threads
                     : static_cast<int>(std::max(1U, std::thread::hardware_concurrency()));
}

std::vector<std::string> placeholder_design_laws(const std::string& file,
                                                 const std::vector<std::string>& sets,
                                                 std::vector<std::string>* names) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return {};  // the load says what is wrong with the file
  std::stringstream text;
  text << in.rdbuf();
  toml::table doc;
  try {
    doc = toml::parse(text.str(), std::string_view(file));
    for (const auto& s : sets) config::apply_set(doc, s, "--set");
  } catch (const std::exception&) {
    return {};  // likewise
  }
  std::vector<std::string> out;
  const toml::array* links = doc["link"].as_array();
  for (std::size_t i = 0; links != nullptr && i < links->size(); ++i) {
    const toml::table* t = links->get(i)->as_table();
    if (t == nullptr || t->get("design_pmf") != nullptr) continue;
    const auto kind = (*t)["kind"].value<std::string>();
    if (!kind || *kind != "network") continue;
    out.push_back(fmt::format("link[{}].design_pmf={}", i, kPlaceholderLaw));
    if (names != nullptr) names->push_back((*t)["name"].value_or(fmt::format("link[{}]", i)));
  }
  return out;
}

RecordedTrace record_link(const Scenario& sc, std::size_t l, std::int64_t runs, int jobs) {
  const std::vector<std::size_t> from = senders(sc, l);
  const std::int64_t periods = sc.run.periods;
  RecordedTrace out;
  for (const std::size_t s : from) {
    const std::int64_t every = sc.model.sensors[s].spec.every;
    out.per_run += (periods + every - 1) / every;
  }
  if (out.per_run * runs > kMaxPackets) {
    throw config::ScenarioError(
        fmt::format("--runs/--periods: recording link '{}' gives {} runs x {} packets, more than "
                    "the {} packets a trace link "
                    "reads",
                    sc.links[l].name, runs, out.per_run, kMaxPackets));
  }
  out.delays.reserve(static_cast<std::size_t>(out.per_run * runs));
  if (sc.links[l].link->network_attachment() != nullptr) {
    record_network_runs(sc, l, runs, jobs, out);
    return out;
  }
  const std::uint64_t seed = sc.run.seed;
  const kernel::SimTime period_ns = kernel::seconds_to_time(sc.run.period);
  std::vector<std::int64_t> copies;
  for (std::int64_t r = 0; r < runs; ++r) {
    const auto run = static_cast<std::uint64_t>(r);
    // As the campaign (sim/run/campaign.cc): a fresh instance, the run's mobility and link stream.
    std::unique_ptr<models::MobilityRun> mobility;
    if (sc.mobility) mobility = sc.mobility->start(run);
    auto link = sc.links[l].link->clone();
    kernel::Rng rng =
        kernel::make_stream(seed, run, kernel::stream_id(kernel::StreamKind::kLink, l));
    models::bind_run(*link, mobility.get(), seed, run);
    link->reset(rng);
    for (std::int64_t k = 0; k < periods; ++k) {
      if (mobility) mobility->advance(k * period_ns);  // the plant event of period k comes first
      for (const std::size_t s : from) {
        if (k % sc.model.sensors[s].spec.every != 0) continue;
        link->advance(k, rng);
        link->transmit_copies(rng, copies);
        out.delays.push_back(copies.empty() ? models::kLost : copies.front());
      }
    }
  }
  return out;
}

int cmd_record_link(const RecordLinkArgs& a) {
  // A record needs no design law: the designs are made on a placeholder where the file has none.
  std::vector<std::string> sets = a.sets, placeholders;
  for (auto& s : placeholder_design_laws(a.file, a.sets, &placeholders)) sets.push_back(s);
  LoadedScenario loaded = load_cases(a.file, sets, a.overrides);
  if (!placeholders.empty() && !a.quiet)
    note_placeholders(*loaded.cases.front().scenario, placeholders);
  const Scenario& first = *loaded.cases.front().scenario;
  std::size_t l = first.links.size();
  std::string names;
  for (std::size_t i = 0; i < first.links.size(); ++i) {
    if (first.links[i].name == a.link) l = i;
    names += (i ? ", " : "") + first.links[i].name;
  }
  if (l == first.links.size()) {
    throw config::ScenarioError(
        fmt::format("--link: expected the name of a [[link]] of {} ({}), got '{}'", a.file,
                    names.empty() ? "it has none" : names, a.link));
  }
  const std::string out = a.out.empty()
                              ? (std::filesystem::path("out") /
                                 ("record_" + std::filesystem::path(a.file).stem().string()))
                                    .string()
                              : a.out;
  std::string index;
  for (const auto& axis : loaded.sweeps) index += csv_field(axis.key) + ",";
  index += "link,file,runs,periods,segment,packets,delivered,delivered_ratio\n";
  std::vector<std::pair<std::string, std::string>> files;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Scenario& sc = *loaded.cases[c].scenario;
    const RecordedTrace t = record_link(sc, l, sc.run.runs, record_jobs(a.threads));
    const std::string name = loaded.cases.size() == 1 ? fmt::format("{}.csv", a.link)
                                                      : fmt::format("{}_case{}.csv", a.link, c);
    const std::int64_t longest =
        t.delays.empty() ? 0 : *std::max_element(t.delays.begin(), t.delays.end());
    if (longest > models::kMaxFitDelay) {  // a trace `fit` refuses: say why now, not there
      std::cerr << fmt::format(
          "ncosim: note: case {}: link '{}' delivered packets up to {} periods late ({:.3g} s at "
          "run.period = {} s); `ncosim fit` takes delays up to {} periods: a longer run.period "
          "fits the network's delays\n",
          c + 1, a.link, longest, static_cast<double>(longest) * sc.run.period, sc.run.period,
          models::kMaxFitDelay);
    }
    std::string csv = "seq,delay\n";
    std::int64_t delivered = 0;
    for (std::size_t i = 0; i < t.delays.size(); ++i) {
      if (t.delays[i] == models::kLost) {
        csv += fmt::format("{},\n", i);
      } else {
        csv += fmt::format("{},{}\n", i, t.delays[i]);
        ++delivered;
      }
    }
    for (const auto& label : loaded.cases[c].labels) index += csv_field(label) + ",";
    const auto packets = static_cast<std::int64_t>(t.delays.size());
    index += fmt::format("{},{},{},{},{},{},{},{}\n", csv_field(a.link), csv_field(name),
                         sc.run.runs, sc.run.periods, t.per_run, packets, delivered,
                         fmt_number(static_cast<double>(delivered) / static_cast<double>(packets)));
    if (!a.quiet) {
      std::cerr << fmt::format(
          "record-link: case {} of {}: {} runs x {} packets, delivered {:.6g}\n", c + 1,
          loaded.cases.size(), sc.run.runs, t.per_run,
          static_cast<double>(delivered) / static_cast<double>(packets));
    }
    files.emplace_back(name, std::move(csv));
  }
  files.emplace_back("record.csv", std::move(index));
  // Everything recorded (bad input already refused): only now is the folder touched.
  prepare_output_dir(out);
  const OutputFolderLock lock(out);  // one writer per folder (sim/files/output_set.h)
  write_files_atomically(out, files);
  std::cout << fmt::format("{} trace(s) of link '{}' and record.csv written to {}/\n",
                           files.size() - 1, a.link, out);
  return 0;
}

}  // namespace ncosim::sim
