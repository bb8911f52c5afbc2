// sim/cmd/ladder_report.h — what `ncosim ladder` (sim/cmd/ladder.h) prints and writes of its
// rungs: the summary on stdout, ladder.csv and ladder.md. Columns: docs/ladder.md.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sim/analysis/compare.h"
#include "sim/cmd/fit_report.h"

namespace ncosim::sim {

// One rung of the ladder: the network itself (the first), or a family's surrogate.
struct Rung {
  std::string name;       // "network" or the family
  std::string note;       // what to know about its fits (loss only, not converged on a link)
  std::string text;       // its scenario file
  double wall = 0.0;      // the campaign's simulation wall time (manifest.json wall_seconds)
  CompareResult compare;  // surrogates: against the network
  std::string compare_csv, compare_md;
};

struct LadderReport {
  std::string file, out;
  double tolerance = 0.0, alpha = 0.0;
  std::int64_t runs = 0, periods = 0;
  std::uint64_t seed = 0;
  double record_seconds = 0.0, fit_seconds = 0.0;
  std::vector<std::string> links;  // one line per network link (link_summary)
  std::vector<Rung> rungs;
};

// "NAME: N scored packets, loss L, delays 0 .. D; BIC selects F; design_pmf [...]".
std::string link_summary(const std::string& name, const FitSet& set,
                         const std::vector<double>& design_pmf);

// Where a surrogate's row stands against the band of +-tolerance around the network's mse:
// "inside" when compare's verdict is `unchanged` and its interval of the relative change lies
// within +-tolerance (equivalence shown); "inconclusive" when the verdict is `unchanged` but the
// interval reaches beyond the band (no significant change, no equivalence either); else compare's
// verdict (`worse`, `better`, ...).
inline constexpr const char* kInside = "inside";
std::string band_verdict(const CompareRow& row, double tolerance);

std::string ladder_summary(const LadderReport& r);
std::string ladder_csv(const LadderReport& r);
std::string ladder_markdown(const LadderReport& r);

}  // namespace ncosim::sim
