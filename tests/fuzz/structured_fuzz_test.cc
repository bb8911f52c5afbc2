// tests/fuzz/structured_fuzz_test.cc — a structured mutation fuzzer over the shipped scenarios.
//
// Each mutant is a shipped scenario (scenarios/*.toml without SUMO, and the CLI test fixture)
// parsed with toml++, changed by 1-3 structural mutations (a leaf replaced by a boundary or
// wrong-typed value, scaled or negated; a key or array element deleted or duplicated; an unknown
// key of random bytes added; a matrix row or column added; a value grafted from another
// scenario), written back as TOML and loaded as `ncosim check` does (load_cases, every design).
// Asserted for every mutant: it loads or fails with ScenarioError (exit 2) whose message starts
// with FILE:LINE; no other exception (std::bad_alloc under the address-space cap included); time
// per mutant under kMutantSeconds of CPU (a long campaign found badly scaled models whose iterative
// jump designs stalled at rounding noise and ran to their 200 000-iteration cap: 16-24 s of CPU
// for one mutant; they now stop when the change stalls, Reliability.BadlyScaledModelStops...).
// A sample of the mutants that load is then run through the executable (`ncosim run --runs 2
// --periods 50`): exit 0, the full output set (the run store included), no NaN or inf in
// summary.csv and runs.csv, and `ncosim export` of the store alone reproduces both byte for byte.
//
// Fixed seed, NCOSIM_FUZZ_MUTANTS mutants (default 3000) within NCOSIM_FUZZ_SECONDS (default 60;
// the test stops early at that budget and reports how far it got). For a long campaign outside
// CI: NCOSIM_FUZZ_MUTANTS=1000000 NCOSIM_FUZZ_SECONDS=0 NCOSIM_FUZZ_SEED=S build/tests/fuzz_test.
// Failing mutants are written to NCOSIM_FUZZ_KEEP (default: the system temp folder).
// NCOSIM_FUZZ_DUMP=DIR writes every mutant (DIR/mutant_N.toml) and the verdict of the load
// (DIR/verdicts.tsv: N, "loaded" or "refused", the error's first line): the schema's agreement with
// `ncosim check` is measured on them (tests/schema/fuzz_schema_test.py).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "sim/scenario/resource_limits.h"
#include "sim/scenario/scenario.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using Rng = std::mt19937_64;

constexpr double kMutantSeconds = 20.0;    // CPU seconds per mutant (load + every design)
constexpr double kMemoryCapBytes = 6e9;    // address space of the test process
constexpr double kLimitMemoryBytes = 1e9;  // --max-memory of the mutants (1000 MB)
constexpr double kLimitWorkFlops = 2e10;   // --max-work of the mutants (20 GFLOP)

// CPU time of this process (the mutants load on this thread; designs do not start threads).
double cpu_seconds() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

long env_long(const char* name, long fallback) {
  const char* v = std::getenv(name);
  return v != nullptr ? std::atol(v) : fallback;
}

struct Seed {
  std::string name;
  toml::table doc;
};

std::vector<Seed> corpus() {
  std::vector<Seed> out;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(fs::path(NCOSIM_SOURCE_DIR) / "scenarios")) {
    if (e.path().extension() == ".toml" &&
        e.path().filename().string().find("sumo") == std::string::npos) {
      files.push_back(e.path());
    }
  }
  files.push_back(fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data" / "base.toml");
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    Seed seed{f.stem().string(), toml::parse_file(f.string())};
    // At most two values per sweep axis and a few runs: the mutants stay cheap to design.
    if (auto* sweeps = seed.doc["sweep"].as_array()) {
      for (auto& sw : *sweeps) {
        if (auto* vals = sw.as_table() ? (*sw.as_table())["values"].as_array() : nullptr) {
          while (vals->size() > 2) vals->pop_back();
        }
      }
    }
    out.push_back(std::move(seed));
  }
  return out;
}

// Every node of the document with the container that holds it.
struct Slot {
  toml::table* table = nullptr;  // holder when a table
  std::string key;
  toml::array* array = nullptr;  // holder when an array
  std::size_t index = 0;
  toml::node* node = nullptr;
};

void collect(toml::table& t, std::vector<Slot>& out) {
  for (auto&& [k, v] : t) {
    out.push_back({&t, std::string(k.str()), nullptr, 0, &v});
    if (auto* sub = v.as_table()) collect(*sub, out);
    if (auto* arr = v.as_array()) {
      for (std::size_t i = 0; i < arr->size(); ++i) {
        toml::node* e = arr->get(i);
        out.push_back({nullptr, "", arr, i, e});
        if (auto* st = e->as_table()) collect(*st, out);
        if (auto* sa = e->as_array()) {
          for (std::size_t j = 0; j < sa->size(); ++j)
            out.push_back({nullptr, "", sa, j, sa->get(j)});
        }
      }
    }
  }
}

std::string random_bytes(Rng& rng, std::size_t max_len) {
  std::string s(std::uniform_int_distribution<std::size_t>(0, max_len)(rng), ' ');
  for (char& c : s) c = static_cast<char>(std::uniform_int_distribution<int>(0, 255)(rng));
  // TOML strings must be UTF-8: keep ASCII (control bytes included, escaped by the writer).
  for (char& c : s) c = static_cast<char>(static_cast<unsigned char>(c) & 0x7F);
  return s;
}

// A value of a random kind, often a boundary.
template <class F>
void with_random_value(Rng& rng, const std::vector<Seed>& seeds, F&& use) {
  static const std::vector<std::int64_t> ints{0,
                                              -1,
                                              1,
                                              2,
                                              3,
                                              7,
                                              16,
                                              62,
                                              63,
                                              64,
                                              100,
                                              1000,
                                              1000000,
                                              1000000000,
                                              2147483648LL,
                                              std::numeric_limits<std::int64_t>::max(),
                                              std::numeric_limits<std::int64_t>::min()};
  const double inf = std::numeric_limits<double>::infinity();
  static const std::vector<double> floats{0.0,    -0.0,         1e-300, 1e-9, 0.5,      0.999999,
                                          1.0,    1.0000001,    2.0,    1e9,  1e300,    -1.0,
                                          -1e300, std::nan(""), inf,    -inf, 4.9e-324, 1e8};
  static const std::vector<std::string> strings{"",
                                                "x",
                                                "S4",
                                                "S1",
                                                "jump",
                                                "kalman_extended",
                                                "sod_jump",
                                                "open_loop",
                                                "delay",
                                                "trace",
                                                "output",
                                                "all",
                                                "lti",
                                                "transfer_function",
                                                "/dev/zero",
                                                ".",
                                                "send_on_delta",
                                                "relay",
                                                "white"};
  switch (std::uniform_int_distribution<int>(0, 9)(rng)) {
    case 0:
    case 1:
      use(toml::value<std::int64_t>(ints[rng() % ints.size()]));
      break;
    case 2:
    case 3:
      use(toml::value<double>(floats[rng() % floats.size()]));
      break;
    case 4:
      use(toml::value<std::string>(strings[rng() % strings.size()]));
      break;
    case 5:
      use(toml::value<std::string>(random_bytes(rng, 12)));
      break;
    case 6:
      use(toml::value<bool>(rng() % 2 == 0));
      break;
    case 7: {
      toml::array a;
      const auto len = rng() % 5;
      for (std::size_t i = 0; i < len; ++i) a.push_back(floats[rng() % floats.size()]);
      use(std::move(a));
      break;
    }
    case 8:
      use(toml::table{});
      break;
    default: {
      // Graft a value from another scenario.
      const Seed& s = seeds[rng() % seeds.size()];
      toml::table copy = s.doc;
      std::vector<Slot> slots;
      collect(copy, slots);
      if (slots.empty()) {
        use(toml::value<std::int64_t>(1));
        break;
      }
      const Slot& sl = slots[rng() % slots.size()];
      sl.node->visit([&](auto&& n) {
        using T = std::decay_t<decltype(n)>;
        use(T(n));
      });
    }
  }
}

void replace(const Slot& s, auto&& value) {
  if (s.table != nullptr) {
    s.table->insert_or_assign(s.key, std::forward<decltype(value)>(value));
  } else {
    s.array->replace(s.array->cbegin() + static_cast<std::ptrdiff_t>(s.index),
                     std::forward<decltype(value)>(value));
  }
}

void mutate(toml::table& doc, Rng& rng, const std::vector<Seed>& seeds) {
  std::vector<Slot> slots;
  collect(doc, slots);
  if (slots.empty()) return;
  const Slot& s = slots[rng() % slots.size()];
  switch (std::uniform_int_distribution<int>(0, 9)(rng)) {
    case 0:
    case 1:
    case 2:
      with_random_value(rng, seeds, [&](auto&& v) { replace(s, std::forward<decltype(v)>(v)); });
      break;
    case 3: {  // scale, negate, shift a number
      static const double factors[] = {10.0, 0.1, -1.0, 1000.0, 1e-3, 0.0, 2.0};
      const double f = factors[rng() % 7];
      if (auto i = s.node->value_exact<std::int64_t>()) {
        const double v = static_cast<double>(*i) * f + static_cast<double>(rng() % 3) - 1.0;
        replace(s,
                toml::value<std::int64_t>(std::fabs(v) < 9e18 ? static_cast<std::int64_t>(v) : 0));
      } else if (auto d = s.node->value_exact<double>()) {
        replace(s, toml::value<double>(*d * f));
      }
      break;
    }
    case 4:
    case 5:  // delete
      if (s.table != nullptr) {
        s.table->erase(s.key);
      } else {
        s.array->erase(s.array->cbegin() + static_cast<std::ptrdiff_t>(s.index));
      }
      break;
    case 6:  // duplicate an array element / append one more row or column
      if (s.array != nullptr) {
        toml::node* e = s.array->get(s.index);
        e->visit([&](auto&& n) {
          using T = std::decay_t<decltype(n)>;
          s.array->push_back(T(n));
        });
      } else if (auto* arr = s.node->as_array(); arr != nullptr && !arr->empty()) {
        for (auto& row : *arr) {
          if (auto* r = row.as_array(); r != nullptr && !r->empty()) r->push_back(0.0);
        }
      }
      break;
    case 7: {  // unknown key of random bytes
      toml::table* t = s.table != nullptr ? s.table : s.node->as_table();
      if (t == nullptr) t = &doc;
      with_random_value(rng, seeds, [&](auto&& v) {
        t->insert_or_assign(random_bytes(rng, 8), std::forward<decltype(v)>(v));
      });
      break;
    }
    case 8:  // a big matrix or array
      if (s.node->is_array() || s.node->is_number()) {
        const std::size_t n = 1 + rng() % 40;
        toml::array m;
        for (std::size_t i = 0; i < n; ++i) {
          toml::array row;
          for (std::size_t j = 0; j < n; ++j) row.push_back(i == j ? 0.5 : 0.0);
          m.push_back(std::move(row));
        }
        replace(s, std::move(m));
      }
      break;
    default:  // a sweep over this key (if the leaf is a scalar)
      if (s.table != nullptr && !s.node->is_table() && !s.node->is_array_of_tables()) {
        // The key path of the slot is not tracked: sweep a top-level [run] key instead.
        toml::array vals;
        vals.push_back(1);
        vals.push_back(2);
        toml::table sw;
        sw.insert("key", rng() % 2 ? "run.seed" : "estimator[0].history");
        sw.insert("values", std::move(vals));
        toml::array* arr = doc["sweep"].as_array();
        if (arr == nullptr) {
          doc.insert_or_assign("sweep", toml::array{});
          arr = doc["sweep"].as_array();
        }
        arr->push_back(std::move(sw));
      }
  }
}

struct Stats {
  long mutants = 0, loaded = 0, refused = 0, runs = 0, failures = 0;
  double max_seconds = 0.0;
  std::string slowest;
};

void keep(const std::string& text, const std::string& what, long index) {
  const char* dir = std::getenv("NCOSIM_FUZZ_KEEP");
  const fs::path p = fs::path(dir ? dir : fs::temp_directory_path().string()) /
                     fmt::format("ncosim_fuzz_fail_{}.toml", index);
  std::ofstream(p) << "# " << what << "\n" << text;
  ADD_FAILURE() << what << " (mutant kept in " << p.string() << ")";
}

bool has_non_finite(const std::string& csv) {
  static const std::regex bad(R"((^|,)(-?nan|-?inf|NaN|-?Inf)(,|$))", std::regex::multiline);
  return std::regex_search(csv, bad);
}

TEST(StructuredFuzz, ShippedScenarioMutantsLoadOrFailWithFileLine) {
  const long mutants = env_long("NCOSIM_FUZZ_MUTANTS", 3000);
  const long budget = env_long("NCOSIM_FUZZ_SECONDS", 60);
  const long seed = env_long("NCOSIM_FUZZ_SEED", 18);
  const long run_every = env_long("NCOSIM_FUZZ_RUN_EVERY", 25);
  const long progress_every =
      env_long("NCOSIM_FUZZ_PROGRESS", 0);  // a progress line every N mutants
  {
    rlimit rl{};
    rl.rlim_cur = rl.rlim_max = static_cast<rlim_t>(kMemoryCapBytes);
    ::setrlimit(RLIMIT_AS, &rl);
  }
  ncosim::sim::set_resource_limits({kLimitMemoryBytes, kLimitWorkFlops});
  const std::vector<Seed> seeds = corpus();
  const fs::path dir = fs::temp_directory_path() / fmt::format("ncosim_fuzz_{}", ::getpid());
  fs::create_directories(dir);
  const std::string file = (dir / "mutant.toml").string();
  const std::regex file_line(
      "^" + std::regex_replace(file, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") +
      R"(:[0-9]+: )");
  Rng rng(static_cast<std::uint64_t>(seed));
  const char* dump_dir = std::getenv("NCOSIM_FUZZ_DUMP");
  std::ofstream verdicts;
  if (dump_dir != nullptr) verdicts.open(fs::path(dump_dir) / "verdicts.tsv");
  Stats st;
  std::map<std::string, double> seconds_by_seed;
  std::map<std::string, long> mutants_by_seed;
  const auto start = std::chrono::steady_clock::now();
  for (long m = 0; m < mutants; ++m) {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (budget > 0 && elapsed > static_cast<double>(budget)) break;
    const Seed& base = seeds[rng() % seeds.size()];
    toml::table doc = base.doc;
    const int count = 1 + static_cast<int>(rng() % 3);
    for (int i = 0; i < count; ++i) mutate(doc, rng, seeds);
    std::ostringstream os;
    os << toml::toml_formatter(doc) << "\n";
    const std::string text = os.str();
    std::ofstream(file, std::ios::binary | std::ios::trunc) << text;
    if (dump_dir != nullptr)
      std::ofstream(fs::path(dump_dir) / fmt::format("mutant_{}.toml", m), std::ios::binary)
          << text;
    ++st.mutants;
    const double t0 = cpu_seconds();
    std::size_t cases = 0;
    bool loaded = false;
    try {
      auto l = ncosim::sim::load_cases(file, {});
      cases = l.cases.size();
      loaded = true;
    } catch (const ncosim::config::ScenarioError& e) {
      ++st.refused;
      if (verdicts.is_open()) {
        const std::string what = e.what();
        verdicts << m << "\trefused\t" << what.substr(0, what.find('\n')) << "\n";
      }
      if (!std::regex_search(e.what(), file_line)) {
        ++st.failures;
        keep(text, fmt::format("exit-2 message without FILE:LINE: {}", e.what()), m);
      }
    } catch (const std::exception& e) {
      ++st.failures;
      keep(text, fmt::format("not a ScenarioError ({}): {}", typeid(e).name(), e.what()), m);
    }
    // CPU time, not wall time: a long campaign runs niced beside other work, and a mutant that
    // waited for the CPU is not slow.
    const double s = cpu_seconds() - t0;
    seconds_by_seed[base.name] += s;
    ++mutants_by_seed[base.name];
    if (s > st.max_seconds) {
      st.max_seconds = s;
      st.slowest = base.name;
    }
    if (s > kMutantSeconds) {
      ++st.failures;
      keep(text, fmt::format("took {:.1f} s of CPU (cap {} s)", s, kMutantSeconds), m);
    }
    if (progress_every > 0 && st.mutants % progress_every == 0) {
      std::printf("structured fuzz: %ld mutants (%ld loaded, %ld runs), %.0f s, failures %ld\n",
                  st.mutants, st.loaded, st.runs,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                  st.failures);
      std::fflush(stdout);
    }
    if (!loaded) continue;
    if (verdicts.is_open()) verdicts << m << "\tloaded\t\n";
    ++st.loaded;
    if (run_every <= 0 || st.loaded % run_every != 0 || cases > 8) continue;
    // The whole path through the executable: tiny campaign, full output set, finite tables.
    ++st.runs;
    const fs::path out = dir / "out";
    fs::remove_all(out);
    const auto o = ncosim::testing::run_shell(
        fmt::format("timeout 120 '{}' run '{}' --runs 2 --periods 60 --set run.warmup=5 --quiet "
                    "--threads 1 --max-memory 1000 "
                    "--max-work 20 --out '{}'",
                    NCOSIM_BINARY, file, out.string()));
    if (o.code != 0) {
      ++st.failures;
      keep(text, fmt::format("run exit {}: {}", o.code, o.output.substr(0, 2000)), m);
      continue;
    }
    for (const char* f : {"summary.csv", "summary.md", "runs.csv", "transmissions.csv",
                          "design.json", "manifest.json", "runs.sqlite"}) {
      if (!fs::exists(out / f)) {
        ++st.failures;
        keep(text, fmt::format("run wrote no {}", f), m);
      }
    }
    // The store is part of the set: re-deriving the exports from it alone gives the same tables.
    const fs::path again = dir / "again";
    fs::remove_all(again);
    const auto e = ncosim::testing::run_shell(fmt::format(
        "timeout 120 '{}' export '{}' --out '{}'", NCOSIM_BINARY, out.string(), again.string()));
    if (e.code != 0) {
      ++st.failures;
      keep(text,
           fmt::format("export of the run's store: exit {}: {}", e.code, e.output.substr(0, 2000)),
           m);
    } else {
      for (const char* f : {"summary.csv", "runs.csv"}) {
        if (ncosim::testing::read_text((out / f).string()) !=
            ncosim::testing::read_text((again / f).string())) {
          ++st.failures;
          keep(text, fmt::format("{} re-derived from the store differs from the run's", f), m);
        }
      }
    }
    for (const char* f : {"summary.csv", "runs.csv"}) {
      if (has_non_finite(ncosim::testing::read_text((out / f).string()))) {
        ++st.failures;
        keep(text, fmt::format("{} holds NaN or inf", f), m);
      }
    }
  }
  const double total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "structured fuzz: seed %ld, %ld mutants (%ld loaded, %ld refused with FILE:LINE, %ld runs) "
      "in %.1f s; "
      "slowest mutant %.2f s (%s); failures %ld\n",
      seed, st.mutants, st.loaded, st.refused, st.runs, total, st.max_seconds, st.slowest.c_str(),
      st.failures);
  for (const auto& [name, secs] : seconds_by_seed) {
    std::printf("  %-36s %5ld mutants, %.1f ms each\n", name.c_str(), mutants_by_seed[name],
                1e3 * secs / static_cast<double>(mutants_by_seed[name]));
  }
  EXPECT_EQ(st.failures, 0);
  EXPECT_GT(st.mutants, 200) << "the budget allowed too few mutants to mean anything";
  fs::remove_all(dir);
}

}  // namespace
