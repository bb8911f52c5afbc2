// models/sensor.cc — [[sensor]] reader.
#include "models/sensor.h"

#include <fmt/format.h>

#include <algorithm>

namespace ncosim::models {

const config::Keys& sensor_keys() {
  static const config::Keys keys{
      config::Key::string("name")
          .optional("\"y1\", \"y2\", ... (1-based position)")
          .help("unique among sensors; names the arrived: column of trajectory.csv"),
      config::Key::matrix("C")
          .or_words({"output"})
          .help("output matrix, one row per output of this sensor (all rows travel in one packet), "
                "n columns; \"output\": the plant's own output matrix (a plant kind with an "
                "output, e.g. transfer_function)"),
      config::Key::matrix("R").help("measurement-noise covariance, ny x ny"),
      config::Key::string("link")
          .optional("ideal link")
          .help("the name of the [[link]] its packets cross (ideal: delay 0, never lost)"),
      config::Key::integer("every")
          .range(1, 1'000'000)
          .says("an integer in 1..1000000 (1e6)")
          .or_default(1)
          .unit("periods")
          .help("sample every `every` periods (multi-rate)"),
      config::Key::integer("buffer").range(0, 62).or_default(0).help(
          "each packet also carries the `buffer` previous samples of this sensor (fewer at the "
          "start), newest first, with their time stamps; 0 on a delay link with independent = "
          "true and with send_on_delta"),
      config::Key::choice("resend_noise", {"same", "fresh"})
          .or_default("same")
          .help("same: a sample re-sent in later buffered packets carries its own noise every time "
                "(physical); fresh: every re-send carries a new noise draw, y = C x[stamp] + v', "
                "and counts as an independent copy (the jump observer's design model for "
                "buffered packets, Dolz et al. example 3)"),
      config::Key::choice("noise", {"gaussian", "uniform"})
          .or_default("gaussian")
          .help("uniform: v_i ~ U(-sqrt(3 R_ii), sqrt(3 R_ii)); R must be diagonal"),
      config::Key::string("policy")
          .optional("\"periodic\"")
          .help("when a sample is sent: \"periodic\", \"send_on_delta\" (its delta below) or "
                "a registered policy (ncosim list)"),
  };
  return keys;
}

int read_link_ref(const config::KeyReader& t, const std::vector<std::string>& links) {
  const auto ref = t.opt_string("link");
  if (!ref) return -1;
  const std::string& name = *ref;
  auto it = std::find(links.begin(), links.end(), name);
  if (it == links.end()) {
    std::string list;
    for (const auto& l : links) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", l);
    const std::string hint = config::did_you_mean(name, links);
    t.fail("link", fmt::format("expected the name of a [[link]] ({}), got \"{}\"{}",
                               list.empty() ? "none defined" : list, name,
                               hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
  }
  return static_cast<int>(it - links.begin());
}

SensorSpec read_sensor(const config::Table& table, const LinearPlant& plant,
                       const std::vector<std::string>& links, int index,
                       const SendPolicyRegistry& policies) {
  const config::KeyReader t(table, sensor_keys());
  SensorSpec s;
  s.name = t.opt_string("name").value_or(fmt::format("y{}", index + 1));
  if (table.is_string("C")) {
    const std::string which = table.choice_or("C", "output", {"output"});
    if (plant.C_out.size() == 0) {
      t.fail(
          "C",
          fmt::format(
              "expected a matrix: C = \"{}\" needs a plant kind with an output (transfer_function)",
              which));
    }
    s.C = plant.C_out;
  } else {
    s.C = t.matrix("C");
  }
  if (s.C.cols() != plant.n()) {
    t.fail("C", fmt::format("expected {} columns (the state size), got a {}x{} matrix", plant.n(),
                            s.C.rows(), s.C.cols()));
  }
  s.R = t.matrix("R");
  config::require_shape(table, "R", s.R, s.C.rows(), s.C.rows());
  config::require_psd(table, "R", s.R);
  s.link = read_link_ref(t, links);
  s.every = static_cast<int>(t.integer("every"));
  s.buffer = static_cast<int>(t.integer("buffer"));
  s.fresh_resend_noise = t.string("resend_noise") == "fresh";
  if (t.string("noise") == "uniform") {
    s.noise = SensorSpec::Noise::kUniform;
    const Eigen::MatrixXd off = s.R - Eigen::MatrixXd(s.R.diagonal().asDiagonal());
    if (off.cwiseAbs().maxCoeff() > 0.0) {
      t.fail("R", "expected a diagonal R with noise = \"uniform\" (independent bounded noises)");
    }
  }
  // `policy` selects a registry entry (its default and "did you mean" are the registry's).
  s.policy = policies.lookup(table, "policy", "periodic").factory(table, s);
  return s;
}

}  // namespace ncosim::models
