// models/controller.cc — relay with dead zone and discrete PI with reference weighting.
#include "models/controller.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace ncosim::models {

double Reference::at(double t) const {
  if (!(period > 0.0)) return low;
  const double phase = t / period - std::floor(t / period);
  // Guard against rounding at the switching instants (t = k * period from an integer k).
  return phase + 1e-9 < 0.5 ? low : high;
}

namespace {

enum class Signal { kTrue, kMeasured, kReceived, kEstimate };

Signal read_signal(const config::KeyReader& t, std::string_view key, bool allow_estimate,
                   std::string* estimator) {
  const std::string v = t.string(key);
  if (v == "true") return Signal::kTrue;
  if (v == "measured") return Signal::kMeasured;
  if (v == "received") return Signal::kReceived;
  if (!allow_estimate || v.empty()) {
    t.fail(key, fmt::format("expected \"true\", \"measured\" or \"received\", got \"{}\"", v));
  }
  *estimator = v;
  return Signal::kEstimate;
}

// The feedback value of sensor `s`, output `i`.
double signal_value(Signal sig, const ControlContext& c, std::size_t s, Eigen::Index i,
                    const Eigen::MatrixXd& C) {
  switch (sig) {
    case Signal::kTrue:
      return (*c.true_output)[s](i);
    case Signal::kMeasured:
      return (*c.measured)[s](i);
    case Signal::kReceived:
      return (*c.received)[s](i);
    case Signal::kEstimate:
      return C.row(i).dot(*c.estimate);
  }
  return 0.0;
}

// ---- relay ----------------------------------------------------------------------------------

struct RelayParams {
  double level = 1.0, dead_zone = 0.0;
  Signal sees = Signal::kMeasured;
  std::vector<std::pair<std::size_t, Eigen::Index>> channels;  // (sensor, output) per input
};

class Relay final : public Controller {
 public:
  explicit Relay(const RelayParams& p) : p_(p) {}
  void compute(const ControlContext& c, Eigen::VectorXd& u) override {
    static const Eigen::MatrixXd none;
    for (Eigen::Index j = 0; j < u.size(); ++j) {
      const auto [s, i] = p_.channels[static_cast<std::size_t>(j)];
      const double y = signal_value(p_.sees, c, s, i, none);
      u(j) = y > p_.dead_zone ? -p_.level : y < -p_.dead_zone ? p_.level : 0.0;
    }
  }

 private:
  const RelayParams& p_;
};

class RelayDesign final : public ControllerDesign {
 public:
  RelayDesign(RelayParams p, Eigen::Index nu) : p_(std::move(p)), nu_(nu) {}
  void bind(const config::Table& t, const std::vector<SensorSpec>& sensors) override {
    std::vector<std::pair<std::size_t, Eigen::Index>> all;  // stacked outputs
    for (std::size_t s = 0; s < sensors.size(); ++s) {
      for (Eigen::Index i = 0; i < sensors[s].ny(); ++i) all.emplace_back(s, i);
    }
    p_.channels.clear();
    if (outputs_.empty()) {
      if (static_cast<Eigen::Index>(all.size()) != nu_) {
        t.fail("kind",
               fmt::format(
                   "expected as many sensor outputs as plant inputs for a relay (output i drives "
                   "input i; or set outputs), got {} outputs and {} inputs",
                   all.size(), nu_));
      }
      p_.channels = all;
      return;
    }
    for (const auto o : outputs_) {
      if (o < 0 || o >= static_cast<std::int64_t>(all.size())) {
        t.fail(
            "outputs",
            fmt::format("expected output indices in 0..{} (the sensors' outputs stacked), got {}",
                        all.size() - 1, o));
      }
      p_.channels.push_back(all[static_cast<std::size_t>(o)]);
    }
  }
  std::vector<std::int64_t> outputs_;
  std::unique_ptr<Controller> instantiate() const override { return std::make_unique<Relay>(p_); }

 private:
  RelayParams p_;
  Eigen::Index nu_;
};

// ---- PI -------------------------------------------------------------------------------------

struct PiParams {
  double kp = 0.0, ki = 0.0, b = 1.0;
  double u_min = -std::numeric_limits<double>::infinity();
  double u_max = std::numeric_limits<double>::infinity();
  Reference ref;
  Signal feedback = Signal::kReceived;
  std::string estimator;
  std::string sensor_name;
  std::size_t sensor = 0;
  Eigen::Index output = 0;
  Eigen::MatrixXd C;  // the sensor's C (for feedback on an estimate)
};

class Pi final : public Controller {
 public:
  explicit Pi(const PiParams& p) : p_(p) {}
  void compute(const ControlContext& c, Eigen::VectorXd& u) override {
    const double r = p_.ref.at(c.t);
    const double y = signal_value(p_.feedback, c, p_.sensor, p_.output, p_.C);
    const double e = r - y;
    const double v = p_.kp * (p_.b * r - y) + integral_;
    const double sat = std::clamp(v, p_.u_min, p_.u_max);
    // Conditional integration (anti-windup): hold the integral while saturated and the error
    // would push further into the limit.
    if (sat == v || (v > p_.u_max && e < 0.0) || (v < p_.u_min && e > 0.0))
      integral_ += p_.ki * c.period * e;
    u.setZero();
    u(0) = sat;
  }
  double reference(const ControlContext& c) const override { return p_.ref.at(c.t); }

 private:
  const PiParams& p_;
  double integral_ = 0.0;
};

class PiDesign final : public ControllerDesign {
 public:
  explicit PiDesign(PiParams p) : p_(std::move(p)) {}
  void bind(const config::Table& t, const std::vector<SensorSpec>& sensors) override {
    if (p_.sensor_name.empty()) {
      p_.sensor = 0;
    } else {
      auto it = std::find_if(sensors.begin(), sensors.end(),
                             [&](const SensorSpec& s) { return s.name == p_.sensor_name; });
      if (it == sensors.end()) {
        std::vector<std::string> names;
        for (const auto& s : sensors) names.push_back(s.name);
        const std::string hint = config::did_you_mean(p_.sensor_name, names);
        t.fail("sensor",
               fmt::format("expected the name of a [[sensor]], got \"{}\"{}", p_.sensor_name,
                           hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
      }
      p_.sensor = static_cast<std::size_t>(it - sensors.begin());
    }
    const SensorSpec& s = sensors[p_.sensor];
    if (p_.output >= s.ny()) {
      t.fail("output", fmt::format("expected an output index in 0..{} of sensor \"{}\", got {}",
                                   s.ny() - 1, s.name, p_.output));
    }
    p_.C = s.C;
  }
  std::string estimate_source() const override {
    return p_.feedback == Signal::kEstimate ? p_.estimator : "";
  }
  std::unique_ptr<Controller> instantiate() const override { return std::make_unique<Pi>(p_); }

 private:
  PiParams p_;
};

using config::Key;

const config::Keys& reference_keys() {
  static const config::Keys keys{
      Key::choice("kind", {"constant", "square"})
          .or_default("constant")
          .help("a constant reference (value) or a square wave (low during the first half of "
                "each period, then high)"),
      Key::number("value")
          .optional("required with kind = \"constant\"")
          .help("the constant reference"),
      Key::number("low")
          .optional("required with kind = \"square\"")
          .help("the square wave's first half-period value"),
      Key::number("high")
          .optional("required with kind = \"square\"")
          .help("the square wave's second half-period value"),
      Key::number("period")
          .optional("required with kind = \"square\"")
          .above(0.0)
          .says("a period > 0 s")
          .unit("s")
          .help("the square wave's period"),
  };
  return keys;
}

Reference read_reference(const config::KeyReader& t) {
  Reference r;
  const config::Table table = t.table("reference");
  const config::KeyReader ref(table, *t.keys().at("reference").fields());
  const std::string kind = ref.string("kind");
  if (kind == "constant") {
    r.low = r.high = ref.number("value");
  } else {
    r.low = ref.number("low");
    r.high = ref.number("high");
    r.period = ref.number("period");
  }
  table.finish();
  return r;
}

}  // namespace

const config::Keys& relay_keys() {
  static const config::Keys keys{
      Key::number("level").or_default(1.0).help("the relay's output magnitude"),
      Key::number("dead_zone")
          .or_default(0.0)
          .min(0.0)
          .noun("a dead zone")
          .help("|y| at or below it gives u = 0"),
      Key::string("sees")
          .or_default("measured")
          .help("\"true\" (C x[k]), \"measured\" (the sensor's newest sample C x + v, whether "
                "sent or not) or \"received\" (the newest value that reached the controller "
                "node)"),
      Key::numbers("outputs")
          .optional("output i drives input i")
          .help("y of input j: outputs[j], 0-based over the sensors' outputs stacked in sensor "
                "order (the default needs as many outputs as inputs)"),
  };
  return keys;
}

const config::Keys& pi_keys() {
  static const config::Keys keys{
      Key::number("kp").or_default(0.0).help("proportional gain"),
      Key::number("ki").or_default(0.0).unit("1/s").help("integral gain"),
      Key::number("b").or_default(1.0).help("reference weight of the proportional term"),
      Key::number("u_min").optional("none").help(
          "lower limit of u: clamped, the integral held while saturated in the same direction"),
      Key::number("u_max").optional("none").help("upper limit of u, > u_min"),
      Key::table("reference").fields(reference_keys()).help("the reference r(t)"),
      Key::string("feedback")
          .or_default("received")
          .help("y: \"received\" (the last received measurement, held between arrivals), "
                "\"measured\", \"true\", or an estimator's name (inferential control: y = C "
                "xhat[k|k] with the sensor's C)"),
      Key::string("sensor").optional("the first sensor").help("the [[sensor]] whose output is y"),
      Key::integer("output")
          .or_default(0)
          .min(0)
          .noun("an output index")
          .help("the index of y among the sensor's outputs"),
  };
  return keys;
}

std::shared_ptr<ControllerDesign> read_relay(const config::Table& table, Eigen::Index nu) {
  const config::KeyReader t(table, relay_keys());
  RelayParams p;
  p.level = t.number("level");
  p.dead_zone = t.number("dead_zone");
  std::string unused;
  p.sees = read_signal(t, "sees", false, &unused);
  auto design = std::make_shared<RelayDesign>(std::move(p), nu);
  if (t.has("outputs")) {
    for (const double v : t.numbers("outputs")) {
      if (v != std::floor(v))
        t.fail("outputs", fmt::format("expected integer output indices, got {}", v));
      design->outputs_.push_back(static_cast<std::int64_t>(v));
    }
    if (static_cast<Eigen::Index>(design->outputs_.size()) != nu) {
      t.fail("outputs", fmt::format("expected {} output indices (one per plant input), got {}", nu,
                                    design->outputs_.size()));
    }
  }
  return design;
}

std::shared_ptr<ControllerDesign> read_pi(const config::Table& table, Eigen::Index nu) {
  const config::KeyReader t(table, pi_keys());
  PiParams p;
  p.kp = t.number("kp");
  p.ki = t.number("ki");
  p.b = t.number("b");
  if (t.has("u_min")) p.u_min = t.number("u_min");
  if (t.has("u_max")) p.u_max = t.number("u_max");
  if (p.u_min >= p.u_max)
    t.fail("u_max", fmt::format("expected u_max > u_min ({}), got {}", p.u_min, p.u_max));
  p.ref = read_reference(t);
  p.feedback = read_signal(t, "feedback", true, &p.estimator);
  p.sensor_name = t.opt_string("sensor").value_or("");
  p.output = t.integer("output");
  (void)nu;  // u(0) is driven; further inputs stay 0
  return std::make_shared<PiDesign>(std::move(p));
}

}  // namespace ncosim::models
