// sumo/vehicle_kinds.cc — the kinds driven by the SUMO vehicles: the `sumo_distance` link and the
// `sumo_vehicle` plant.
#include <fmt/format.h>

#include <cmath>
#include <iostream>

#include "config/keys.h"
#include "kernel/time.h"
#include "models/plant_process.h"
#include "sumo/channel.h"
#include "sumo/sumo.h"
#include "sumo/traffic.h"

namespace ncosim::sumo {

namespace {

// Reception from the distance between two vehicles (or a vehicle and a fixed receiver) at
// send time; each packet's draws come from (seed, run, sender, receiver, sequence number).
class DistanceLink final : public models::Link,
                           public models::LinkReporting,
                           public models::RunBinding {
 public:
  DistanceLink(std::shared_ptr<const Mobility> mobility, int sender, int receiver, double rx,
               double ry, Channel channel, double period, std::uint64_t sender_hash,
               std::uint64_t receiver_hash)
      : mobility_(std::move(mobility)),
        sender_(sender),
        receiver_(receiver),
        rx_(rx),
        ry_(ry),
        channel_(std::move(channel)),
        period_(period),
        sender_hash_(sender_hash),
        receiver_hash_(receiver_hash) {}

  std::unique_ptr<models::Link> clone() const override {
    return std::make_unique<DistanceLink>(*this);
  }
  const models::LinkReporting* reporting() const override { return this; }
  models::RunBinding* run_binding() override { return this; }
  LossModel loss_model() const override { return LossModel::kPosition; }
  // Position-driven losses come in bursts no model fixes.
  std::optional<double> mean_loss_burst(std::optional<int> gap) const override {
    (void)gap;
    return std::nullopt;
  }

  void bind_run(const models::MobilityRun* mobility, std::uint64_t seed,
                std::uint64_t run) override {
    run_ = mobility;
    key_ = stream_key(seed, run, sender_hash_, receiver_hash_);
    seq_ = 0;
  }

  std::int64_t transmit(kernel::Rng&) override {
    const std::uint64_t seq = seq_++;
    if (run_ == nullptr) return models::kLost;
    const double d =
        distance(run_->vehicle(sender_), receiver_ >= 0 ? &run_->vehicle(receiver_) : nullptr);
    if (!(d >= 0.0)) return models::kLost;  // a vehicle not in the network
    if (keyed_uniform(key_, seq, 0) >= channel_.reception_probability(d)) return models::kLost;
    return channel_.delay_periods(d, period_, keyed_uniform(key_, seq, 1));
  }

  // The design law: p(d) and the delay law averaged over the recorded realisations at the
  // control instants of the horizon.
  std::vector<double> delay_pmf(int max_delay) const override {
    std::vector<double> pmf(static_cast<std::size_t>(max_delay) + 1, 0.0);
    std::int64_t count = 0;
    for_each_distance([&](double d) {
      ++count;
      if (!(d >= 0.0)) return;
      const double p = channel_.reception_probability(d);
      for (int j = 0; j <= max_delay; ++j)
        pmf[static_cast<std::size_t>(j)] += p * channel_.delay_period_probability(d, period_, j);
    });
    for (double& p : pmf) p /= static_cast<double>(std::max<std::int64_t>(count, 1));
    return pmf;
  }

  double loss_probability() const override {
    double sum = 0.0;
    std::int64_t count = 0;
    for_each_distance([&](double d) {
      ++count;
      if (d >= 0.0) sum += channel_.reception_probability(d);
    });
    return 1.0 - sum / static_cast<double>(std::max<std::int64_t>(count, 1));
  }

 private:
  double distance(const models::VehicleState& s, const models::VehicleState* r) const {
    if (!s.present || (r != nullptr && !r->present)) return -1.0;
    return r != nullptr ? std::hypot(s.x - r->x, s.y - r->y) : std::hypot(s.x - rx_, s.y - ry_);
  }

  template <class F>
  void for_each_distance(F&& f) const {
    const auto period_ns = kernel::seconds_to_time(period_);
    for (const Recording& rec : mobility_->recordings()) {
      const std::int64_t step_ns = rec.step_ms * 1'000'000;
      const std::int64_t horizon = (rec.frames - 1) * step_ns;
      for (std::int64_t t = 0; t <= horizon; t += period_ns) {
        const std::int64_t frame = std::min(t / step_ns, rec.frames - 1);
        f(distance(rec.at(frame, sender_), receiver_ >= 0 ? &rec.at(frame, receiver_) : nullptr));
      }
    }
  }

  std::shared_ptr<const Mobility> mobility_;
  int sender_, receiver_;
  double rx_, ry_;
  Channel channel_;
  double period_;
  std::uint64_t sender_hash_, receiver_hash_;
  const models::MobilityRun* run_ = nullptr;
  std::uint64_t key_ = 0, seq_ = 0;
};

using config::Key;

// The keys of sumo_distance: the link's own, then the channel's (declared and read by
// sumo/channel.cc; some defaults are the preset's).
const config::Keys& sumo_distance_keys() {
  static const config::Keys keys =
      config::Keys{
          Key::string("sender").help("transmitting vehicle: a vehicle id driving in the horizon"),
          Key::string("receiver")
              .optional("one of receiver, receiver_position required")
              .help("receiving vehicle: a vehicle id other than sender"),
          Key::numbers("receiver_position")
              .optional("")
              .unit("m")
              .help(
                  "a fixed receiver (roadside unit) at [x, y] in SUMO network coordinates, finite"),
          Key::string("receiver_name")
              .optional("rsu@X,Y")
              .help("the fixed receiver's name in the draw key"),
      } +
      channel_keys();
  return keys;
}

const config::Keys& sumo_vehicle_keys() {
  static const config::Keys keys{
      Key::string("vehicle").help(
          "the SUMO vehicle: an id that drives during the horizon in every realisation (else "
          "exit 2 naming this key)"),
      Key::choice("model", {"constant_velocity", "constant_acceleration"})
          .or_default("constant_velocity")
          .help("design model: white acceleration (constant_velocity, n = 2) or white jerk "
                "(constant_acceleration, n = 3)"),
      Key::number("q")
          .above(0.0)
          .says("a positive process-noise intensity")
          .unit("(m/s^2)^2 s (CV) or (m/s^3)^2 s (CA)")
          .help("intensity of the white noise driving the last state"),
      Key::vector("x0").optional("zeros").help("the design's initial state (n entries)"),
  };
  return keys;
}

std::unique_ptr<models::Link> read_sumo_distance(const config::Table& table,
                                                 const models::LinkContext& ctx) {
  const config::Table& t = table;
  const config::KeyReader r(table, sumo_distance_keys());
  auto mobility = std::dynamic_pointer_cast<Mobility>(ctx.mobility);
  if (!mobility)
    t.fail("kind", "expected a [sumo] table (the vehicles' mobility) for a sumo_distance link");
  const int sender = mobility->vehicle(t, "sender");
  const std::string sender_id = r.string("sender");
  int receiver = -1;
  double rx = 0.0, ry = 0.0;
  std::string receiver_id;
  if (t.has("receiver")) {
    receiver = mobility->vehicle(t, "receiver");
    receiver_id = r.string("receiver");
    if (receiver == sender) t.fail("receiver", "expected a receiver other than the sender");
  } else if (t.has("receiver_position")) {
    const auto p = r.numbers("receiver_position");
    if (p.size() != 2 || !std::isfinite(p[0]) || !std::isfinite(p[1])) {
      t.fail("receiver_position", "expected [x, y] in network coordinates (m)");
    }
    rx = p[0];
    ry = p[1];
    receiver_id = r.opt_string("receiver_name").value_or(fmt::format("rsu@{},{}", rx, ry));
  } else {
    t.fail_here(
        "expected `receiver` (a vehicle id) or `receiver_position` ([x, y] of a roadside unit)");
  }
  Channel ch = read_channel(t);
  return std::make_unique<DistanceLink>(std::move(mobility), sender, receiver, rx, ry,
                                        std::move(ch), ctx.period, name_hash(sender_id),
                                        name_hash(receiver_id));
}

// The declared kinematic design model of a SUMO vehicle's longitudinal motion. The true
// state (position along the route, speed[, acceleration]) comes from SUMO.
models::LinearPlant read_sumo_vehicle(const config::Table& table, double period) {
  const config::KeyReader t(table, sumo_vehicle_keys());
  table.allow("vehicle");  // bound to the mobility by the scenario reader (vehicle_key)
  const std::string model = t.string("model");
  const double q = t.number("q");
  const Eigen::Index n = model == "constant_velocity" ? 2 : 3;
  Eigen::MatrixXd Ac = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index i = 0; i + 1 < n; ++i) Ac(i, i + 1) = 1.0;
  Eigen::MatrixXd Gc = Eigen::MatrixXd::Zero(n, 1);
  Gc(n - 1, 0) = 1.0;
  models::LinearPlant p = models::discretise(Ac, Eigen::MatrixXd::Zero(n, 0), Gc,
                                             Eigen::MatrixXd::Constant(1, 1, q), period);
  p.vehicle_key = "vehicle";
  p.process = models::vehicle_process;
  if (t.has("x0")) {
    p.x0 = t.vector("x0");
    if (p.x0.size() != n)
      t.fail("x0", fmt::format("expected {} entries (the state size), got {}", n, p.x0.size()));
  }
  return p;
}

}  // namespace

void register_links(models::LinkRegistry& registry) {
  registry.add("sumo_distance",
               "reception p(d) from the distance between SUMO vehicles: sender, receiver | "
               "receiver_position, "
               "preset, tx_power, threshold, fading, sigma, m, m_bounds, mac, rate, size, aifsn, "
               "cw, backoff, t1, t2",
               sumo_distance_keys(), read_sumo_distance);
  // The vehicles it reads, announced before the cases are built (announce_vehicles).
  declare_vehicle_keys(VehicleTable::kLink, "sumo_distance", {"sender", "receiver"});
}

void register_plants(models::PlantRegistry& registry) {
  registry.add(
      "sumo_vehicle",
      "a SUMO vehicle's longitudinal motion (position, speed[, acceleration]) as true state; "
      "design "
      "model: model = constant_velocity | constant_acceleration, q (intensity), vehicle, x0",
      sumo_vehicle_keys(), read_sumo_vehicle);
  declare_vehicle_keys(VehicleTable::kPlant, "sumo_vehicle", {"vehicle"});
}

std::shared_ptr<models::MobilitySource> make_mobility(const config::Table& t,
                                                      const config::RunSettings& run,
                                                      const std::string& dir) {
  return std::make_shared<Mobility>(t, run, dir);
}

int channel_command(const std::string& preset, bool csv, bool gnuplot, double max_distance,
                    double step) {
  Channel ch;
  try {
    ch = make_preset(preset);
  } catch (const std::invalid_argument&) {
    std::string list;
    for (const auto& n : preset_names()) list += (list.empty() ? "" : ", ") + n;
    std::cerr << fmt::format("ncosim: expected a channel preset ({}), got '{}'\n", list, preset);
    return 2;
  }
  if (!(max_distance > 0.0 && step > 0.0 && max_distance / step <= 1e6)) {
    std::cerr << "ncosim: expected --max-distance > 0 and --step > 0 (at most 1e6 rows)\n";
    return 2;
  }
  if (gnuplot) {
    std::cout << channel_gnuplot(ch, preset + ".csv", preset + ".png");
    return 0;
  }
  if (!csv) std::cout << preset << ": " << preset_help(preset) << "\n";
  std::cout << channel_table(ch, max_distance, step, csv);
  return 0;
}

}  // namespace ncosim::sumo
