// models/sensor.cc — [[sensor]] reader.
#include "models/sensor.h"

#include <fmt/format.h>

#include <algorithm>

namespace ncosim::models {

int read_link_ref(const sim::Table& t, const std::vector<std::string>& links) {
  if (!t.has("link")) return -1;
  const std::string name = t.string("link");
  auto it = std::find(links.begin(), links.end(), name);
  if (it == links.end()) {
    std::string list;
    for (const auto& l : links) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", l);
    const std::string hint = sim::did_you_mean(name, links);
    t.fail("link", fmt::format("expected the name of a [[link]] ({}), got \"{}\"{}",
                               list.empty() ? "none defined" : list, name,
                               hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
  }
  return static_cast<int>(it - links.begin());
}

SensorSpec read_sensor(const sim::Table& t, const LinearPlant& plant,
                       const std::vector<std::string>& links, int index,
                       const SendPolicyRegistry& policies) {
  SensorSpec s;
  s.name = t.string_or("name", fmt::format("y{}", index + 1));
  if (t.is_string("C")) {
    const std::string which = t.choice_or("C", "output", {"output"});
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
  sim::require_shape(t, "R", s.R, s.C.rows(), s.C.rows());
  sim::require_psd(t, "R", s.R);
  s.link = read_link_ref(t, links);
  const auto every = t.integer_or("every", 1);
  if (every < 1 || every > 1'000'000)
    t.fail("every", fmt::format("expected an integer in 1..1000000 (1e6), got {}", every));
  s.every = static_cast<int>(every);
  const auto buffer = t.integer_or("buffer", 0);
  if (buffer < 0 || buffer > 62)
    t.fail("buffer", fmt::format("expected an integer in 0..62, got {}", buffer));
  s.buffer = static_cast<int>(buffer);
  s.fresh_resend_noise = t.choice_or("resend_noise", "same", {"same", "fresh"}) == "fresh";
  const std::string noise = t.choice_or("noise", "gaussian", {"gaussian", "uniform"});
  if (noise == "uniform") {
    s.noise = SensorSpec::Noise::kUniform;
    const Eigen::MatrixXd off = s.R - Eigen::MatrixXd(s.R.diagonal().asDiagonal());
    if (off.cwiseAbs().maxCoeff() > 0.0) {
      t.fail("R", "expected a diagonal R with noise = \"uniform\" (independent bounded noises)");
    }
  }
  s.policy = policies.lookup(t, "policy", "periodic").factory(t, s);
  return s;
}

}  // namespace ncosim::models
