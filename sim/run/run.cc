// sim/run/run.cc — one Monte Carlo run: the event handlers route each component's output to the
// next (plant -> sensors -> links -> estimators -> controller -> actuation -> plant, and every
// outcome to the recorder). Event order within an instant is the kernel's phase order
// (kernel/event_queue.h).
#include "sim/run/run.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "kernel/event_queue.h"
#include "kernel/rng.h"
#include "models/actuator.h"
#include "models/plant_process.h"
#include "models/sensor_process.h"
#include "sim/run/link_report.h"
#include "sim/run/network_path.h"
#include "sim/run/run_recorder.h"

namespace ncosim::sim {

namespace {

// Adapts a member function to an EventHandler.
template <class T, void (T::*Method)(kernel::SimTime, std::uint64_t)>
class MemberHandler final : public kernel::EventHandler {
 public:
  explicit MemberHandler(T* self) : self_(self) {}
  void handle(kernel::SimTime now, std::uint64_t arg) override { (self_->*Method)(now, arg); }

 private:
  T* self_;
};

// From the controller's u[k] to what the plant applies: the `actuation_delay` ring, then the
// actuator links (models/actuator.h) or ideal actuation.
class ActuationPath {
 public:
  ActuationPath(const Scenario& sc, std::uint64_t run) {
    const Eigen::Index nu = sc.model.plant.nu();
    queue_.assign(static_cast<std::size_t>(sc.input.actuation_delay), Eigen::VectorXd::Zero(nu));
    applied_ = Eigen::VectorXd::Zero(nu);
    sent_ = applied_;
    if (!sc.model.actuators.empty()) {
      std::vector<const models::Link*> links;
      for (const auto& l : sc.links) links.push_back(l.link.get());
      std::vector<models::ActuatorSpec> specs;
      for (const auto& a : sc.model.actuators) specs.push_back(a.spec);
      stage_ = std::make_unique<models::ActuatorStage>(specs, links, sc.run.seed, run);
      applied_ = stage_->applied();  // u0: held before the first delivery
    }
  }
  // u[k] computed now acts after `actuation_delay` periods (zero before the first).
  void actuate(const Eigen::VectorXd& u) {
    const Eigen::VectorXd* acting = &u;
    if (!queue_.empty()) {
      delayed_ = queue_[head_];
      queue_[head_] = u;
      head_ = (head_ + 1) % queue_.size();
      acting = &delayed_;
    }
    if (stage_) {
      mode_ = stage_->actuate(*acting);  // the plant applies what arrives
      applied_ = stage_->applied();
    } else {
      applied_ = *acting;
    }
    sent_ = *acting;  // what the estimators know at the next update: what was sent to act now
  }
  const Eigen::VectorXd& applied() const { return applied_; }
  const Eigen::VectorXd& sent() const { return sent_; }
  bool has_links() const { return stage_ != nullptr; }
  int mode() const { return mode_; }  // the delivery pattern of the last actuation
  models::ActuatorStage* stage() { return stage_.get(); }

  // Commands delivered over a network (sim/run/network_path.h): the delivery pattern's bits of
  // the commands resolved before this plant step, and what the plant applies now.
  void resolved(int mode) {
    mode_ |= mode;
    applied_ = stage_->applied();
  }

 private:
  std::vector<Eigen::VectorXd> queue_;  // ring of the last actuation_delay inputs
  std::size_t head_ = 0;
  Eigen::VectorXd delayed_, applied_, sent_;
  std::unique_ptr<models::ActuatorStage> stage_;  // nullptr: ideal actuation
  int mode_ = 0;
};

class RunSimulation {
 public:
  RunSimulation(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace, ReplayLog* log,
                std::vector<models::LinkCounters>* link_counters, ErrorCurve* curve)
      : sc_(sc),
        period_ns_(kernel::seconds_to_time(sc.run.period)),
        log_(log),
        link_out_(link_counters),
        mobility_(sc.mobility ? sc.mobility->start(run) : nullptr),
        actuation_(sc, run),
        recorder_(sc, estimators_, trace, curve),
        open_handler_(this),
        arrival_handler_(this),
        close_handler_(this) {
    const std::uint64_t seed = sc.run.seed;
    const models::LinearPlant& plant = sc.model.plant;
    models::PlantRun pr{seed, run, mobility_.get(), sc.plant_vehicle, &sc.disturbance, sc.recentre};
    plant_ = models::make_plant_process(plant, pr);
    signals_.x = plant.x0;
    signals_.drive = Eigen::VectorXd::Zero(plant.n());
    signals_.recentre = Eigen::VectorXd::Zero(plant.n());
    known_drive_ = Eigen::VectorXd::Zero(plant.n());
    nominal_drive_ = !actuation_.has_links() && plant_->drive_is_nominal();
    u_ = Eigen::VectorXd::Zero(plant.nu());
    sensors_.reserve(sc.model.sensors.size());
    for (std::size_t s = 0; s < sc.model.sensors.size(); ++s) {
      const auto& spec = sc.model.sensors[s].spec;
      sensors_.emplace_back(spec, static_cast<int>(s), seed, run);
      true_output_.push_back(Eigen::VectorXd::Zero(spec.ny()));
      measured_.push_back(Eigen::VectorXd::Zero(spec.ny()));
      received_.push_back(Eigen::VectorXd::Zero(spec.ny()));
      received_stamp_.push_back(-1);
      sample_order_.push_back(s);
    }
    next_sample_.assign(sensors_.size(), 0);
    due_.reserve(sensors_.size());
    sending_.reserve(sensors_.size());
    // Links: one fresh instance per run.
    for (std::size_t l = 0; l < sc.links.size(); ++l) {
      LinkState ls;
      ls.link = sc.links[l].link->clone();
      ls.rng = kernel::make_stream(seed, run, kernel::stream_id(kernel::StreamKind::kLink, l));
      models::bind_run(*ls.link, mobility_.get(), seed, run);
      ls.link->reset(ls.rng);
      links_.push_back(std::move(ls));
    }
    network_ = NetworkPath::start(sc, mobility_.get(), run);  // null without [[network]]
    if (link_out_ != nullptr) {
      flows_ = link_flows(sc);
      flow_of_ = flow_index(sc, flows_);
      link_counters_.resize(flows_.size());
    }
    for (const auto& e : sc.estimators) estimators_.push_back(e.design->instantiate());
    controller_ = sc.input.controller->instantiate();
    input_rng_ = kernel::make_stream(seed, run, kernel::stream_id(kernel::StreamKind::kInput, 0));
    ctx_.period = sc.run.period;
    ctx_.x = &signals_.x;
    ctx_.true_output = &true_output_;
    ctx_.measured = &measured_;
    ctx_.received = &received_;
    ctx_.rng = &input_rng_;
    sees_outputs_ = sc.input.controller->sees_outputs();
  }

  RunMetrics execute() {
    const std::int64_t periods = sc_.run.periods;
    queue_.reserve(64);
    queue_.schedule(0, kernel::Phase::kPlant, &open_handler_, 0);
    queue_.schedule(0, kernel::Phase::kEstimate, &close_handler_, 0);
    queue_.run_until((periods - 1) * period_ns_);
    if (link_out_ != nullptr) {
      if (models::ActuatorStage* stage = actuation_.stage()) {
        for (std::size_t a = 0; a < flow_of_.actuator.size(); ++a) {
          const int f = flow_of_.actuator[a];
          if (f >= 0) link_counters_[static_cast<std::size_t>(f)] = std::move(stage->counters()[a]);
        }
      }
      if (network_) stack_counters();
      for (auto& c : link_counters_) c.close();
      *link_out_ = std::move(link_counters_);
    }
    return recorder_.finish();
  }

  // record_network_link: the network path's record of link `link` (sim/run/network_path.h).
  NetworkPath& network() { return *network_; }

 private:
  struct LinkState {
    std::unique_ptr<models::Link> link;
    kernel::Rng rng;
  };

  // What each network node's stack did in the run, on the rows of its link's sensors.
  void stack_counters() {
    for (std::size_t s = 0; s < sensors_.size(); ++s) {
      if (auto k = network_->stack(sensors_[s].spec().link)) {
        link_counters_[static_cast<std::size_t>(flow_of_.sensor[s])].stack = std::move(*k);
      }
    }
  }

  // The networks through `now` (sim/run/network_path.h): a packet delivered in ((k - 1) T, k T]
  // arrives at k T (this period's arrival phase); a dropped one is counted lost.
  void advance_networks(kernel::SimTime now) {
    network_->advance(now, network_fate_, actuation_.stage(), link_out_ != nullptr);
  }
  void on_network_fate(std::size_t id, std::int64_t arrival) {
    const models::Packet& p = pool_[id];
    const bool delivered = arrival != models::kLost;
    if (link_out_ != nullptr) {
      link_counters_[static_cast<std::size_t>(flow_of_.sensor[static_cast<std::size_t>(p.sensor)])]
          .record(delivered ? arrival - p.stamps[0] : models::kLost, -1);
    }
    if (delivered && arrival < sc_.run.periods) {
      queue_.schedule(arrival * period_ns_, kernel::Phase::kArrival, &arrival_handler_, id);
    } else {
      free_.push_back(id);
    }
  }

  std::int64_t period_of(kernel::SimTime t) const { return (t + period_ns_ - 1) / period_ns_; }
  bool reschedule(kernel::SimTime now, std::int64_t step, kernel::Phase phase,
                  kernel::EventHandler* h, std::uint64_t arg) {
    const std::int64_t next = now / period_ns_ + step;
    if (next >= sc_.run.periods) return false;
    queue_.schedule(next * period_ns_, phase, h, arg);
    return true;
  }

  // The phases every period has at its start (plant step, sampling, sending) and at its end
  // (estimator updates, control, actuation, metrics) are one event each: no other component
  // schedules events in those phases, so running them in phase order inside one event keeps
  // the kernel's order (kernel/event_queue.h) while a period costs two dispatches, plus one
  // per packet arrival, instead of eight or more.
  void on_open(kernel::SimTime now, std::uint64_t) {
    const std::int64_t k = now / period_ns_;
    if (network_ && network_->commands() && k > 0) {  // commands arrived before this plant step
      advance_networks(now - 1);
      actuation_.resolved(network_->resolve_commands(k, *actuation_.stage()));
    }
    on_plant(now, k);
    // The sensors due now sample in the order their samples were scheduled, as separate
    // events would: a sampled sensor moves to the end of sample_order_ (its next sample is
    // the newest scheduled). With different `every`, that is not the sensors' index order.
    due_.clear();
    std::size_t kept = 0;
    for (const std::size_t s : sample_order_) {
      if (next_sample_[s] == k) {
        due_.push_back(s);
      } else {
        sample_order_[kept++] = s;
      }
    }
    sending_.clear();
    for (const std::size_t s : due_) {
      sample_order_[kept++] = s;
      next_sample_[s] = k + sensors_[s].spec().every;
      if (on_sample(k, s)) sending_.push_back(s);
    }
    if (network_) network_->move_nodes(now);
    for (const std::size_t s : sending_) on_send(k, s);
    if (network_) advance_networks(now);
    reschedule(now, 1, kernel::Phase::kPlant, &open_handler_, 0);
  }

  void on_close(kernel::SimTime now, std::uint64_t) {
    const std::int64_t k = now / period_ns_;
    on_estimate(k);
    on_control(k);
    actuation_.actuate(u_);
    if (network_ && network_->commands()) network_->send_commands(k, now);
    recorder_.on_period(k, signals_.x, signals_.mode, u_, reference_);
    reschedule(now, 1, kernel::Phase::kEstimate, &close_handler_, 0);
  }

  // x[k] from x[k-1] and the input applied during period k - 1.
  void on_plant(kernel::SimTime now, std::int64_t k) {
    if (mobility_) mobility_->advance(now);  // the kernel's clock drives the mobility (SUMO)
    if (plant_->step(k, actuation_.applied(), signals_)) recorder_.on_state(k, signals_.x);
    if (k > 0 && !nominal_drive_) {
      // The estimators know what was sent (nominal Bu), not what was applied.
      known_drive_.noalias() = sc_.model.plant.Bu * actuation_.sent();
      known_drive_ += signals_.recentre;
    }
    if (k > 0 && actuation_.has_links()) signals_.mode = actuation_.mode();
  }

  // Returns whether the sample is to be sent.
  bool on_sample(std::int64_t k, std::size_t s) {
    models::SensorProcess& sensor = sensors_[s];
    const bool send = sensor.sample(k, signals_.x);
    measured_[s] = sensor.newest();
    recorder_.on_sample(s, k, send, sensor.newest(), sensor.held());
    return send;
  }

  // The link decides the copies and their delays; each copy is a packet in flight.
  void on_send(std::int64_t k, std::size_t s) {
    models::SensorProcess& sensor = sensors_[s];
    if (sensor.spec().link < 0) {
      deliver_copy(s, k, 0, false);
      return;
    }
    const int link = sensor.spec().link;
    if (network_ && network_->carries(link)) {  // a node of a network: the network decides
      if (!network_->in_traffic(link)) {        // a vehicle not in the traffic sends nothing
        network_->lost(link, s, k);
        if (link_out_ != nullptr)
          link_counters_[static_cast<std::size_t>(flow_of_.sensor[s])].record(models::kLost, -1);
        return;
      }
      network_->send(link, s, take_packet(s, k, false), k);
      return;
    }
    LinkState& ls = links_[static_cast<std::size_t>(link)];
    ls.link->advance(k, ls.rng);
    const int state = models::state_of(*ls.link);
    ls.link->transmit_copies(ls.rng, delays_);
    if (link_out_ != nullptr)
      link_counters_[static_cast<std::size_t>(flow_of_.sensor[s])].record(delays_, state);
    const bool independent = ls.link->independent_copies();
    for (std::size_t c = 0; c < delays_.size(); ++c) {
      if (independent && c > 0)
        sensor.redraw_newest(signals_.x);  // the design model: own noise per copy
      deliver_copy(s, k, delays_[c], independent);
    }
  }

  void deliver_copy(std::uint64_t s, std::int64_t k, std::int64_t delay, bool independent) {
    if (delay >= sc_.run.periods - k) return;  // beyond the horizon (k + delay may not fit)
    const std::int64_t arrival = k + delay;
    queue_.schedule(arrival * period_ns_, kernel::Phase::kArrival, &arrival_handler_,
                    take_packet(s, k, independent));
  }

  // A packet of the pool holding sensor s's sample of period k: its id.
  std::size_t take_packet(std::uint64_t s, std::int64_t k, bool independent) {
    std::size_t id;
    if (!free_.empty()) {
      id = free_.back();
      free_.pop_back();
    } else {
      id = pool_.size();
      pool_.emplace_back();
    }
    sensors_[s].pack(pool_[id], k, independent);
    return id;
  }

  void on_arrival(kernel::SimTime now, std::uint64_t id) {
    const std::int64_t k = period_of(now);
    const models::Packet& p = pool_[id];
    for (std::size_t e = 0; e < estimators_.size(); ++e)
      recorder_.on_used(e, k, estimators_[e]->on_packet(p, k));
    recorder_.on_arrival(p.sensor);
    const auto ps = static_cast<std::size_t>(p.sensor);
    if (p.count > 0 &&
        p.stamps[0] > received_stamp_[ps]) {  // the newest sample seen at the controller node
      received_stamp_[ps] = p.stamps[0];
      received_[ps] = p.values.head(received_[ps].size());
    }
    if (log_ != nullptr && static_cast<std::size_t>(k) < log_->limit) {
      log_->packets.push_back(p);
      log_->packet_period.push_back(k);
    }
    free_.push_back(id);
  }

  void on_estimate(std::int64_t k) {
    const est::PeriodInput in{actuation_.sent(), nominal_drive_ ? signals_.drive : known_drive_};
    for (auto& e : estimators_) e->on_period(k, in);
    if (log_ != nullptr && log_->u.size() < log_->limit) {
      log_->u.push_back(in.u);
      log_->drive.push_back(in.drive);
    }
  }

  void on_control(std::int64_t k) {
    ctx_.k = k;
    ctx_.t = static_cast<double>(ctx_.k) * sc_.run.period;
    if (sees_outputs_) {
      for (std::size_t s = 0; s < sensors_.size(); ++s)
        true_output_[s].noalias() = sensors_[s].spec().C * signals_.x;
    }
    if (sc_.input.source_index >= 0) {
      estimate_ = estimators_[static_cast<std::size_t>(sc_.input.source_index)]->state();
      ctx_.estimate = &estimate_;
    }
    controller_->compute(ctx_, u_);
    if (sees_outputs_) reference_ = controller_->reference(ctx_);
  }

  const Scenario& sc_;
  kernel::SimTime period_ns_;
  ReplayLog* log_;
  std::vector<models::LinkCounters>* link_out_;
  std::vector<LinkFlow> flows_;
  FlowIndex flow_of_;
  std::vector<models::LinkCounters> link_counters_;
  std::unique_ptr<models::MobilityRun>
      mobility_;  // before the plant and links: they hold a pointer to it
  std::unique_ptr<models::PlantProcess> plant_;
  models::PlantSignals signals_;
  Eigen::VectorXd known_drive_;  // nominal Bu u(sent) + recentre, when the applied drive differs
  bool nominal_drive_ = true;
  std::vector<models::SensorProcess> sensors_;
  std::vector<LinkState> links_;
  std::unique_ptr<NetworkPath> network_;  // the run's networks (null without [[network]])
  NetworkPath::PacketFate network_fate_ = [this](std::size_t id, std::int64_t arrival) {
    on_network_fate(id, arrival);
  };
  std::vector<std::int64_t> delays_;
  std::vector<std::size_t>
      sample_order_;  // the sensors in the order their next samples were scheduled
  std::vector<std::int64_t> next_sample_;  // the period of each sensor's next sample
  std::vector<std::size_t> due_;           // the sensors that sample in this period, in order
  std::vector<std::size_t> sending_;       // the sensors whose sample of this period is sent
  std::vector<models::Packet> pool_;       // packets in flight, reused
  std::vector<std::size_t> free_;
  std::vector<std::unique_ptr<est::Estimator>> estimators_;
  // The controller node: what it can know, and its output.
  std::unique_ptr<models::Controller> controller_;
  kernel::Rng input_rng_;
  models::ControlContext ctx_;
  bool sees_outputs_ = false;
  std::vector<Eigen::VectorXd> true_output_, measured_, received_;
  std::vector<std::int64_t> received_stamp_;
  Eigen::VectorXd estimate_, u_;
  double reference_ = std::nan("");
  ActuationPath actuation_;
  RunRecorder recorder_;
  kernel::EventQueue queue_;
  MemberHandler<RunSimulation, &RunSimulation::on_open> open_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_arrival> arrival_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_close> close_handler_;
};

}  // namespace

RunMetrics execute_run(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace,
                       ReplayLog* log, std::vector<models::LinkCounters>* links,
                       ErrorCurve* curve) {
  RunSimulation sim(sc, run, trace, log, links, curve);
  return sim.execute();
}

std::vector<RecordedPacket> record_network_link(const Scenario& sc, std::uint64_t run,
                                                std::size_t link) {
  std::vector<RecordedPacket> out;
  RunSimulation sim(sc, run, nullptr, nullptr, nullptr, nullptr);
  sim.network().record(static_cast<int>(link), &out);
  sim.execute();
  sim.network().drain(kernel::seconds_to_time(sc.run.period));
  std::stable_sort(out.begin(), out.end(), [](const RecordedPacket& a, const RecordedPacket& b) {
    return a.period != b.period ? a.period < b.period : a.sensor < b.sensor;
  });
  return out;
}

std::vector<double> time_estimators(const Scenario& sc, const ReplayLog& log,
                                    std::chrono::nanoseconds budget) {
  std::vector<double> out;
  const std::size_t periods = log.u.size();
  for (const auto& entry : sc.estimators) {
    std::vector<double> samples;
    const auto begin = std::chrono::steady_clock::now();
    for (int rep = 0; rep < 15 && (rep < 1 || std::chrono::steady_clock::now() - begin < budget);
         ++rep) {
      auto est = entry.design->instantiate();
      std::size_t next = 0;
      const auto t0 = std::chrono::steady_clock::now();
      for (std::size_t k = 0; k < periods; ++k) {
        const auto kk = static_cast<std::int64_t>(k);
        while (next < log.packets.size() && log.packet_period[next] == kk) {
          est->on_packet(log.packets[next], kk);
          ++next;
        }
        est->on_period(kk, est::PeriodInput{log.u[k], log.drive[k]});
      }
      const auto t1 = std::chrono::steady_clock::now();
      samples.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() /
                        static_cast<double>(std::max<std::size_t>(periods, 1)));
    }
    std::sort(samples.begin(), samples.end());
    out.push_back(samples[samples.size() / 2]);
  }
  return out;
}

}  // namespace ncosim::sim
