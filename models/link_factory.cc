// models/link_factory.cc — [[link]] readers: parameters range-checked, errors at their line.
#include "models/link_factory.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>

#include "config/input_files.h"
#include "config/keys.h"

namespace ncosim::models {

namespace {

using config::Key;

// `step` of the Markov-chain links.
Key step_key() {
  return Key::choice("step", {"period", "packet"})
      .or_default("period")
      .help(
          "when the chain moves: once per control period (time-driven) or once per packet sent "
          "on the link");
}

const config::Keys& delay_keys() {
  static const config::Keys keys =
      config::Keys{
          Key::numbers("pmf")
              .optional("required unless delivery")
              .probability()
              .entries(1, 0)
              .help(
                  "pmf[d] = P[delay = d periods], d = 0..len-1, lost with probability 1 - sum: "
                  "non-empty, entries >= 0, sum <= 1 (+1e-9); with independent, each entry in [0, "
                  "1], any sum"),
          Key::number("delivery")
              .optional("none (use pmf)")
              .probability()
              .help("not with pmf: pmf[d] = delivery * shape[d] / sum(shape), one scalar (the "
                    "probability that a sample is delivered; with independent, the scale of every "
                    "copy's probability) to sweep or search with `ncosim find`"),
          Key::numbers("shape")
              .optional("[1.0] (delay 0)")
              .min(0.0)
              .help("only with delivery: relative weights of the delays 0..len-1 (entries >= 0 and "
                    "finite, at least one > 0)"),
          Key::boolean("independent")
              .or_default(false)
              .help("true: every d is an independent copy, delivered with probability pmf[d]; a "
                    "sample may arrive 0..len times (sensors on the link need buffer = 0)"),
      }
          .require_one_of({"pmf", "delivery"});
  return keys;
}

const config::Keys& bernoulli_keys() {
  static const config::Keys keys{
      Key::number("loss").probability().or_default(0.0).help("P[lost]"),
      Key::integer("delay")
          .range(0, 1'000'000)
          .or_default(0)
          .unit("periods")
          .help("delay of every delivered packet"),
  };
  return keys;
}

const config::Keys& negative_binomial_keys() {
  static const config::Keys keys{
      Key::integer("successes")
          .range(1, 10000)
          .help("r: the delay is the number of failures before the r-th success"),
      Key::number("p")
          .above(0.0)
          .max(1.0)
          .noun("a probability")
          .help("success probability of a trial (p = 1: delay 0)"),
      Key::number("loss").probability().or_default(0.0).help("P[lost], before the delay is drawn"),
  };
  return keys;
}

const config::Keys& arrival_cdf_keys() {
  static const config::Keys keys{
      Key::numbers("cdf").probability().entries(1, 0).help(
          "lambda_h = P[delay <= h periods] for h = 0, 1, ...: non-empty, entries in [0, 1], "
          "non-decreasing"),
      Key::number("tail")
          .optional("the last cdf value")
          .probability()
          .help("lambda_h for every h >= len(cdf), >= the last cdf value (1 - tail is lost)"),
  };
  return keys;
}

const config::Keys& gilbert_elliott_keys() {
  static const config::Keys keys{
      Key::number("p_good_to_bad")
          .optional("required unless mean_loss")
          .probability()
          .help("P[good -> bad] per step"),
      Key::number("p_bad_to_good")
          .optional("required unless mean_loss")
          .probability()
          .help("P[bad -> good] per step; p_good_to_bad + p_bad_to_good > 0"),
      Key::number("loss_good").probability().or_default(0.0).help("P[lost] in the good state"),
      Key::number("loss_bad").probability().or_default(1.0).help("P[lost] in the bad state"),
      step_key(),
      Key::number("mean_loss")
          .optional("none")
          .probability()
          .help("stationary loss probability P, loss_good < P < loss_bad; with mean_burst, "
                "instead of p_good_to_bad and p_bad_to_good"),
      Key::number("mean_burst")
          .optional("none")
          .min(1.0)
          .says("a finite mean burst length >= 1")
          .help("mean length of a run of consecutive lost packets: >= 1 and in the range these "
                "losses allow (below)"),
  };
  return keys;
}

const config::Keys& markov_keys() {
  static const config::Keys keys{
      Key::matrix("transition")
          .probability()
          .help("S x S transition matrix of the chain: square, entries >= 0, rows sum to 1 "
                "(+-1e-9)"),
      Key::numbers("loss").probability().help("per-state loss probability: S entries in [0, 1]"),
      Key::ragged("delay_pmf")
          .optional("delay 0")
          .probability()
          .help("per-state delay law of a delivered packet (loss is `loss`): S rows of any "
                "length, entries >= 0 summing to 1 (+-1e-9)"),
      Key::numbers("initial")
          .optional("the stationary law")
          .probability()
          .help("law of the first state: S entries >= 0 summing to 1 (+-1e-9)"),
      step_key(),
  };
  return keys;
}

const config::Keys& trace_keys() {
  static const config::Keys keys{
      Key::string("file").help(
          "the CSV of seq,delay (empty delay = lost), relative to the scenario file's folder "
          "unless absolute: a readable regular file of at most 10^9 bytes, lines of at most 4096 "
          "bytes, at most 5e7 packets and (without segment) at least sum ceil(periods / every) "
          "rows over the sensors on this link"),
      Key::integer("segment")
          .optional("none (every run replays from row 0)")
          .help("rows per run, 1 .. the trace's rows (and at least the rows one run sends): run "
                "r replays segment r mod floor(rows / segment) from its start (the layout of "
                "`ncosim record-link`)"),
  };
  return keys;
}

std::vector<double> read_pmf(const config::KeyReader& r, std::string_view key) {
  std::vector<double> pmf = r.numbers(key);
  if (pmf.empty()) r.fail(key, "expected at least one probability, got an empty array");
  config::require_subprobability(r.table(), key, pmf);
  return pmf;
}

// `delivery` + `shape`: pmf[d] = delivery * shape[d] / sum(shape), so that one scalar (the
// probability that a sample is delivered at all, or with `independent`, the scale of every
// copy's probability) can be swept or searched by `ncosim find`.
std::vector<double> read_delivery(const config::KeyReader& t) {
  if (t.has("pmf")) t.fail("delivery", "expected either pmf or delivery (with shape), got both");
  const double delivery = t.number("delivery");
  std::vector<double> shape = t.has("shape") ? t.numbers("shape") : std::vector<double>{1.0};
  if (shape.empty()) t.fail("shape", "expected at least one weight, got an empty array");
  double sum = 0.0;
  for (std::size_t d = 0; d < shape.size(); ++d) {
    if (!(shape[d] >= 0.0 && std::isfinite(shape[d]))) {
      t.fail("shape",
             fmt::format("expected non-negative finite weights, got {} at index {}", shape[d], d));
    }
    sum += shape[d];
  }
  if (!(sum > 0.0)) t.fail("shape", "expected at least one positive weight, got all zero");
  for (double& w : shape) w = delivery * w / sum;
  return shape;
}

std::unique_ptr<Link> read_delay(const config::Table& table, const LinkContext&) {
  const config::KeyReader t(table, delay_keys());
  const bool independent = t.boolean("independent");
  if (t.has("delivery")) return std::make_unique<DelayPmfLink>(read_delivery(t), independent);
  if (t.has("shape")) t.fail("shape", "expected shape only with delivery, got no delivery");
  if (!independent) return std::make_unique<DelayPmfLink>(read_pmf(t, "pmf"), false);
  // Independent copies: each pmf[d] is its own probability (they need not sum to <= 1).
  std::vector<double> pmf = t.numbers("pmf");
  if (pmf.empty()) t.fail("pmf", "expected at least one probability, got an empty array");
  for (std::size_t d = 0; d < pmf.size(); ++d) {
    if (!(pmf[d] >= 0.0 && pmf[d] <= 1.0)) {
      t.fail("pmf", fmt::format("expected probabilities in [0, 1], got {} at index {}", pmf[d], d));
    }
  }
  return std::make_unique<DelayPmfLink>(std::move(pmf), true);
}

std::unique_ptr<Link> read_bernoulli(const config::Table& t, const LinkContext&) {
  const config::KeyReader r(t, bernoulli_keys());
  return std::make_unique<BernoulliLink>(r.number("loss"), r.integer("delay"));
}

std::unique_ptr<Link> read_negative_binomial(const config::Table& table, const LinkContext&) {
  const config::KeyReader t(table, negative_binomial_keys());
  const auto r = t.integer("successes");
  const double p = t.number("p");
  const double loss = t.number("loss");
  return std::make_unique<NegativeBinomialLink>(static_cast<int>(r), p, loss);
}

std::unique_ptr<Link> read_arrival_cdf(const config::Table& table, const LinkContext&) {
  const config::KeyReader t(table, arrival_cdf_keys());
  std::vector<double> cdf = t.numbers("cdf");
  if (cdf.empty()) t.fail("cdf", "expected at least one value, got an empty array");
  for (std::size_t h = 0; h < cdf.size(); ++h) {
    if (!(cdf[h] >= 0.0 && cdf[h] <= 1.0)) {
      t.fail("cdf", fmt::format("expected probabilities in [0, 1], got {} at h = {}", cdf[h], h));
    }
    if (h > 0 && cdf[h] < cdf[h - 1]) {
      t.fail("cdf",
             fmt::format("expected a non-decreasing P[delay <= h], got {} after {} at h = {}",
                         cdf[h], cdf[h - 1], h));
    }
  }
  const double tail = t.opt_number("tail").value_or(cdf.back());
  if (tail < cdf.back()) {
    t.fail("tail", fmt::format("expected tail >= the last cdf value {}, got {}", cdf.back(), tail));
  }
  return std::make_unique<ArrivalCdfLink>(std::move(cdf), tail);
}

// `step`: "period" (default: the chain moves once per control period) or "packet".
MarkovLink::Step read_step(const config::KeyReader& t) {
  return t.string("step") == "packet" ? MarkovLink::Step::kPacket : MarkovLink::Step::kPeriod;
}

std::unique_ptr<Link> read_gilbert_elliott(const config::Table& table, const LinkContext&) {
  const config::KeyReader t(table, gilbert_elliott_keys());
  const MarkovLink::Step step = read_step(t);
  const double lg = t.number("loss_good");
  const double lb = t.number("loss_bad");
  const bool by_mean = t.has("mean_loss") || t.has("mean_burst");
  if (by_mean) {
    for (const char* key : {"p_good_to_bad", "p_bad_to_good"}) {
      if (t.has(key))
        t.fail(key, fmt::format("expected either {} or mean_loss and mean_burst, got both", key));
    }
    const GilbertElliottByMean ge =
        gilbert_elliott_by_mean(t.number("mean_loss"), t.number("mean_burst"), lg, lb);
    if (!ge.error.empty()) t.fail(ge.error_key, ge.error);
    return make_gilbert_elliott(ge.p_good_to_bad, ge.p_bad_to_good, lg, lb, step);
  }
  const double gb = t.number("p_good_to_bad");
  const double bg = t.number("p_bad_to_good");
  if (gb + bg <= 0.0) {
    t.fail("p_bad_to_good",
           fmt::format(
               "expected p_good_to_bad + p_bad_to_good > 0 (a chain that can move), got {} + {}",
               gb, bg));
  }
  return make_gilbert_elliott(gb, bg, lg, lb, step);
}

std::unique_ptr<Link> read_markov(const config::Table& table, const LinkContext&) {
  const config::KeyReader t(table, markov_keys());
  const MarkovLink::Step step = read_step(t);
  const Eigen::MatrixXd T = t.matrix("transition");
  if (T.rows() != T.cols()) {
    t.fail("transition", fmt::format("expected a square matrix, got {}x{}", T.rows(), T.cols()));
  }
  const Eigen::Index s = T.rows();
  for (Eigen::Index i = 0; i < s; ++i) {
    if (T.row(i).minCoeff() < 0.0 || std::abs(T.row(i).sum() - 1.0) > 1e-9) {
      t.fail("transition",
             fmt::format("expected non-negative rows summing to 1, got row {} summing to {}", i,
                         T.row(i).sum()));
    }
  }
  std::vector<double> loss = t.numbers("loss");
  if (static_cast<Eigen::Index>(loss.size()) != s) {
    t.fail("loss", fmt::format("expected {} per-state loss probabilities, got {}", s, loss.size()));
  }
  for (double p : loss) {
    if (!(p >= 0.0 && p <= 1.0))
      t.fail("loss", fmt::format("expected probabilities in [0, 1], got {}", p));
  }
  std::vector<std::vector<double>> delay;
  if (t.has("delay_pmf")) {
    delay = t.ragged("delay_pmf");
    if (static_cast<Eigen::Index>(delay.size()) != s) {
      t.fail("delay_pmf", fmt::format("expected one pmf per state ({}), got {}", s, delay.size()));
    }
    for (const auto& pmf : delay) {
      double sum = 0.0;
      for (double p : pmf) {
        if (p < 0.0)
          t.fail("delay_pmf", fmt::format("probabilities must be non-negative, got {}", p));
        sum += p;
      }
      if (std::abs(sum - 1.0) > 1e-9) {
        t.fail(
            "delay_pmf",
            fmt::format("expected each state's delay pmf to sum to 1 (loss is `loss`), got {:.6g}",
                        sum));
      }
    }
  }
  std::vector<double> initial;
  if (t.has("initial")) {
    initial = t.numbers("initial");
    if (static_cast<Eigen::Index>(initial.size()) != s) {
      t.fail("initial", fmt::format("expected {} probabilities, got {}", s, initial.size()));
    }
    config::require_subprobability(table, "initial", initial);
    double sum = 0.0;
    for (double p : initial) sum += p;
    if (std::abs(sum - 1.0) > 1e-9)
      t.fail("initial", fmt::format("expected probabilities summing to 1, got {:.6g}", sum));
  }
  return std::make_unique<MarkovLink>(T, std::move(loss), std::move(delay), std::move(initial),
                                      step);
}

std::unique_ptr<Link> read_trace(const config::Table& table, const LinkContext& ctx) {
  const config::KeyReader t(table, trace_keys());
  const std::string file = t.string("file");
  std::filesystem::path path(file);
  if (path.is_relative() && !ctx.scenario_dir.empty())
    path = std::filesystem::path(ctx.scenario_dir) / path;
  try {
    int first_row_line = 1;
    auto delays = load_trace(path.string(), &first_row_line);
    config::note_input_file(
        path.string());  // the trace's content is part of the campaign's identity
    if (delays.empty()) t.fail("file", fmt::format("trace '{}' holds no packet", path.string()));
    if (ctx.check_trace_delay) {
      // The runs count delivered packets per delay up to the largest one
      // (sim/scenario/resource_limits.h).
      std::size_t largest = delays.size();
      for (std::size_t i = 0; i < delays.size(); ++i) {
        if (delays[i] && (largest == delays.size() || *delays[i] > *delays[largest])) largest = i;
      }
      if (largest < delays.size()) {
        ctx.check_trace_delay(path.string(), first_row_line + static_cast<int>(largest),
                              *delays[largest],
                              fmt::format("{}:{}: key '{}'", table.file(), table.line_of("file"),
                                          table.key_path("file")));
      }
    }
    // `segment`: rows per run (run r replays segment r mod floor(rows / segment)).
    std::size_t segment = 0;
    if (t.has("segment")) {
      const auto s = t.integer("segment");
      if (s < 1 || s > static_cast<std::int64_t>(delays.size())) {
        t.fail("segment", fmt::format("expected an integer in 1..{} (the trace's rows), got {}",
                                      delays.size(), s));
      }
      segment = static_cast<std::size_t>(s);
    }
    return std::make_unique<TraceLink>(std::move(delays), segment);
  } catch (const TraceError& e) {
    if (e.line <= 0)
      t.fail("file",
             fmt::format("expected a readable trace file, got '{}' ({})", path.string(), e.what()));
    // The error is in the trace: its file and line first, then the key that named it.
    // format_error escapes every byte that is not printable (file names included).
    throw config::ScenarioError(config::format_error(
        e.file, e.line, "",
        fmt::format("{} (the trace named by {}:{}: key '{}')", e.what(), table.file(),
                    table.line_of("file"), table.key_path("file"))));
  }
}

}  // namespace

void register_links(LinkRegistry& registry) {
  registry.add("delay",
               "delay d periods with probability pmf[d], lost otherwise: pmf (or delivery, shape), "
               "independent",
               delay_keys(), read_delay);
  registry.add("bernoulli", "lost with probability loss, else delayed `delay` periods: loss, delay",
               bernoulli_keys(), read_bernoulli);
  registry.add("negative_binomial",
               "negative-binomial delay (failures before `successes` successes of probability p): "
               "successes, p, loss",
               negative_binomial_keys(), read_negative_binomial);
  registry.add("arrival_cdf", "Schenato's lambda_h = P[delay <= h]: cdf, tail", arrival_cdf_keys(),
               read_arrival_cdf);
  registry.add("gilbert_elliott",
               "two-state Markov loss: p_good_to_bad, p_bad_to_good (or mean_loss, mean_burst), "
               "loss_good, loss_bad, step",
               gilbert_elliott_keys(), read_gilbert_elliott);
  registry.add(
      "markov",
      "finite Markov chain (per period or per packet): transition, loss, delay_pmf, initial, step",
      markov_keys(), read_markov);
  registry.add("trace", "replay a recorded CSV of seq,delay (empty delay = lost): file[, segment]",
               trace_keys(), read_trace);
}

}  // namespace ncosim::models
