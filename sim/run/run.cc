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
#include "network/network.h"
#include "sim/run/link_report.h"
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

  // Actuator links over a network (models::ActuatorStage::networked): channel a's command of
  // period k is a packet of network sender senders[a] (-1: not networked), sent at the close of
  // period k (after the control law); it is applied if ns-3 delivers it to the actuator's node
  // before (k + 1) T, the next plant step (phase order: the plant steps first at (k + 1) T, so a
  // command received exactly then is late, as a sample received then is used after that step).
  void attach_network(std::vector<int> senders) {
    sender_ = std::move(senders);
    command_.assign(sender_.size(), -1);
    arrived_.assign(sender_.size(), 0);
  }
  bool networked() const { return !sender_.empty(); }
  void send_commands(network::Session& net, std::int64_t k, kernel::SimTime now) {
    for (std::size_t a = 0; a < sender_.size(); ++a) {
      if (sender_[a] < 0) continue;
      net.send(sender_[a], static_cast<std::uint64_t>(k), now);  // the id: its period
      command_[a] = k;
      arrived_[a] = 0;
    }
  }
  // Whether `f` is a command's fate (else a sensor's): counted (when `count`) with its delay in
  // periods after its sending period, kept when it is in time for its period.
  bool on_fate(const network::Fate& f, std::int64_t period_ns, bool count) {
    const auto at = std::find(sender_.begin(), sender_.end(), f.sender);
    if (at == sender_.end()) return false;
    const auto a = static_cast<std::size_t>(at - sender_.begin());
    const auto k = static_cast<std::int64_t>(f.id);
    const bool delivered = f.drop == network::Drop::kNone;
    const std::int64_t delay = (f.time - k * period_ns) / period_ns;
    if (count) stage_->counters()[a].record(delivered ? delay : models::kLost, -1);
    if (delivered && delay == 0 && command_[a] == k) arrived_[a] = 1;
    return true;
  }
  // Before the plant step of period k: the commands of period k - 1 applied or not.
  void resolve(std::int64_t k) {
    for (std::size_t a = 0; a < sender_.size(); ++a) {
      if (sender_[a] < 0 || command_[a] != k - 1) continue;
      mode_ |= stage_->resolve(static_cast<int>(a), arrived_[a] != 0);
      command_[a] = -1;
    }
    applied_ = stage_->applied();
  }

 private:
  std::vector<Eigen::VectorXd> queue_;  // ring of the last actuation_delay inputs
  std::size_t head_ = 0;
  Eigen::VectorXd delayed_, applied_, sent_;
  std::unique_ptr<models::ActuatorStage> stage_;  // nullptr: ideal actuation
  int mode_ = 0;
  std::vector<int> sender_;            // per channel: its network sender, -1 (empty: none)
  std::vector<std::int64_t> command_;  // per channel: the period of its command in flight, or -1
  std::vector<char> arrived_;          // per channel: that command arrived in time
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
    start_networks(seed, run);
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
      stack_counters();
      for (auto& c : link_counters_) c.close();
      *link_out_ = std::move(link_counters_);
    }
    return recorder_.finish();
  }

  // Records the fate of every packet sensor `sensors` send over network link `link` instead of
  // counting (record_network_link).
  void record(std::size_t link, std::vector<RecordedPacket>* out) {
    record_link_ = static_cast<int>(link);
    record_out_ = out;
  }

  // After the run's last period, ns-3 goes on (nothing else does) until every recorded packet has
  // its fate, for at most kDrainNs of simulated time.
  void drain() {
    constexpr kernel::SimTime kDrainNs = 60'000'000'000;
    const kernel::SimTime end = network_now_ + kDrainNs;
    for (kernel::SimTime t = network_now_ + period_ns_; pending_ > 0 && t <= end; t += period_ns_)
      advance_networks(t);
  }

 private:
  struct LinkState {
    std::unique_ptr<models::Link> link;
    kernel::Rng rng;
    int sender = -1;   // its sender in the network session (a link of kind network), else -1
    int vehicle = -1;  // the SUMO vehicle its network node rides, else -1
  };

  // The run's networks (network/network.h): every link that is a node of one is a sender, then
  // the [[background]] nodes, whose traffic stays inside the session (counted, never a fate).
  void start_networks(std::uint64_t seed, std::uint64_t run) {
    if (sc_.networks.empty()) return;
    std::vector<network::Sender> senders;
    for (auto& ls : links_) {
      if (const models::NetworkAttachment* a = ls.link->network_attachment()) {
        ls.sender = static_cast<int>(senders.size());
        ls.vehicle = a->vehicle;
        senders.push_back(network::Sender{a->network, a->bytes, a->x, a->y, a->z});
      }
    }
    // An actuator's network link (its own: the reader refuses one shared) sends downlink.
    std::vector<int> actuator_senders;
    for (const auto& am : sc_.model.actuators) {
      const int l = am.spec.link;
      const int sender = l >= 0 ? links_[static_cast<std::size_t>(l)].sender : -1;
      if (sender >= 0) senders[static_cast<std::size_t>(sender)].downlink = true;
      actuator_senders.push_back(sender);
    }
    if (std::any_of(actuator_senders.begin(), actuator_senders.end(), [](int x) { return x >= 0; }))
      actuation_.attach_network(std::move(actuator_senders));
    first_background_ = static_cast<int>(senders.size());
    senders.insert(senders.end(), sc_.background.begin(), sc_.background.end());
    std::vector<std::shared_ptr<const network::NetworkDesign>> designs;
    for (const auto& n : sc_.networks) designs.push_back(n.design);
    network_ = network::Session::start(designs, senders, seed, run);
  }

  // What each network node's stack did in the run (network::Session::counters), on the rows of
  // its link's sensors.
  void stack_counters() {
    for (std::size_t s = 0; s < sensors_.size(); ++s) {
      const int l = sensors_[s].spec().link;
      if (l < 0 || links_[static_cast<std::size_t>(l)].sender < 0) continue;
      const network::MacCounters c = network_->counters(links_[static_cast<std::size_t>(l)].sender);
      models::StackCounters k;
      k.attempts = static_cast<std::int64_t>(c.attempts);
      k.retries = static_cast<std::int64_t>(c.retries);
      for (const std::uint64_t d : c.dropped) k.drops.push_back(static_cast<std::int64_t>(d));
      k.busy_ns = c.busy_ns;
      k.simulated_ns = network_now_;
      link_counters_[static_cast<std::size_t>(flow_of_.sensor[s])].stack = std::move(k);
    }
  }

  // Lockstep with ns-3 at the start of period k, after its sends: every packet the networks
  // delivered in ((k - 1) T, k T] arrives at k T (this period's arrival phase); a dropped one is
  // counted lost.
  void advance_networks(kernel::SimTime now) {
    fates_.clear();
    network_->advance_to(now, fates_);
    network_now_ = now;
    for (const network::Fate& f : fates_) {
      if (actuation_.networked() && actuation_.on_fate(f, period_ns_, link_out_ != nullptr))
        continue;
      const auto id = static_cast<std::size_t>(f.id);
      const models::Packet& p = pool_[id];
      const std::int64_t arrival = period_of(f.time);
      const bool delivered = f.drop == network::Drop::kNone;
      if (link_out_ != nullptr) {
        link_counters_[static_cast<std::size_t>(
                           flow_of_.sensor[static_cast<std::size_t>(p.sensor)])]
            .record(delivered ? arrival - p.stamps[0] : models::kLost, -1);
      }
      if (record_out_ != nullptr && id < record_slot_.size() && record_slot_[id] >= 0) {
        (*record_out_)[static_cast<std::size_t>(record_slot_[id])].delay =
            delivered ? arrival - p.stamps[0] : models::kLost;
        record_slot_[id] = -1;
        --pending_;
      }
      if (delivered && arrival < sc_.run.periods) {
        queue_.schedule(arrival * period_ns_, kernel::Phase::kArrival, &arrival_handler_, id);
      } else {
        free_.push_back(id);
      }
    }
  }

  // The network nodes that ride SUMO vehicles are where their vehicles are at this period's
  // start, from then on (before its sends); a vehicle not in the traffic puts its node out of
  // everyone's range (network::kAway).
  void move_network_nodes(kernel::SimTime now) {
    constexpr double kAntenna = 1.5;  // m above the road
    const auto place = [&](int vehicle, auto&& move) {
      const models::VehicleState& v = mobility_->vehicle(vehicle);
      move(v.x, v.y, v.present ? kAntenna : network::kAway);
    };
    for (const LinkState& ls : links_) {
      if (ls.vehicle < 0) continue;
      place(ls.vehicle,
            [&](double x, double y, double z) { network_->move_sender(ls.sender, x, y, z, now); });
    }
    for (std::size_t b = 0; b < sc_.background.size(); ++b) {
      if (sc_.background[b].vehicle < 0) continue;
      place(sc_.background[b].vehicle, [&](double x, double y, double z) {
        network_->move_sender(first_background_ + static_cast<int>(b), x, y, z, now);
      });
    }
    for (std::size_t n = 0; n < sc_.networks.size(); ++n) {
      if (sc_.networks[n].sink_vehicle < 0) continue;
      place(sc_.networks[n].sink_vehicle, [&](double x, double y, double z) {
        network_->move_sink(static_cast<int>(n), x, y, z, now);
      });
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
    if (actuation_.networked() && k > 0) {  // the commands that arrived before this plant step
      advance_networks(now - 1);
      actuation_.resolve(k);
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
    if (network_) move_network_nodes(now);
    for (const std::size_t s : sending_) on_send(k, s);
    if (network_) advance_networks(now);
    reschedule(now, 1, kernel::Phase::kPlant, &open_handler_, 0);
  }

  void on_close(kernel::SimTime now, std::uint64_t) {
    const std::int64_t k = now / period_ns_;
    on_estimate(k);
    on_control(k);
    actuation_.actuate(u_);
    if (actuation_.networked()) actuation_.send_commands(*network_, k, now);
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
    LinkState& ls = links_[static_cast<std::size_t>(sensor.spec().link)];
    if (ls.sender >= 0) {  // a node of a network: the network decides (advance_networks)
      const bool recorded = record_out_ != nullptr && sensor.spec().link == record_link_;
      if (ls.vehicle >= 0 && !mobility_->vehicle(ls.vehicle).present) {
        // A vehicle not in the traffic sends nothing: the packet is lost.
        if (link_out_ != nullptr)
          link_counters_[static_cast<std::size_t>(flow_of_.sensor[s])].record(models::kLost, -1);
        if (recorded) record_out_->push_back(RecordedPacket{k, s, models::kLost});
        return;
      }
      const std::size_t id = take_packet(s, k, false);
      if (recorded) {
        if (record_slot_.size() < pool_.size()) record_slot_.resize(pool_.size(), -1);
        record_slot_[id] = static_cast<std::int64_t>(record_out_->size());
        record_out_->push_back(RecordedPacket{k, s, models::kLost});
        ++pending_;
      }
      network_->send(ls.sender, id, k * period_ns_);
      return;
    }
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
  std::unique_ptr<network::Session> network_;  // the run's networks (null without [[network]])
  std::vector<network::Fate> fates_;
  int first_background_ = 0;         // the session's index of the first [[background]] node
  kernel::SimTime network_now_ = 0;  // where ns-3 is (its last advance_to)
  int record_link_ = -1;             // the network link being recorded (record_network_link)
  std::vector<RecordedPacket>* record_out_ = nullptr;
  std::vector<std::int64_t> record_slot_;  // per pool packet: its row in record_out_, or -1
  std::int64_t pending_ = 0;               // recorded packets without a fate yet
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
  sim.record(link, &out);
  sim.execute();
  sim.drain();
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
