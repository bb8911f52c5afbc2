// sim/campaign.cc — the event-driven simulation of one run, and the campaign over threads.
#include "sim/campaign.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/random/normal_distribution.hpp>
#include <boost/random/uniform_01.hpp>
#include <boost/random/uniform_real_distribution.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <condition_variable>
#include <mutex>
#include <system_error>
#include <thread>

#include "kernel/check.h"
#include "kernel/event_queue.h"
#include "kernel/rng.h"
#include "models/actuator.h"

namespace ncosim::sim {

namespace {

// Adapts a member function to an EventHandler.
template <class T, void (T::*Method)(SimTime, std::uint64_t)>
class MemberHandler final : public EventHandler {
 public:
  explicit MemberHandler(T* self) : self_(self) {}
  void handle(SimTime now, std::uint64_t arg) override { (self_->*Method)(now, arg); }

 private:
  T* self_;
};

// Standard normal vector from a Boost.Random stream.
void draw_normal(Rng& rng, Eigen::VectorXd& out) {
  boost::random::normal_distribution<double> normal(0.0, 1.0);
  for (Eigen::Index i = 0; i < out.size(); ++i) out(i) = normal(rng);
}

// Unit-variance noise of a sensor: standard normal, or uniform on [-sqrt 3, sqrt 3].
void draw_sensor_noise(Rng& rng, models::SensorSpec::Noise kind, Eigen::VectorXd& out) {
  if (kind == models::SensorSpec::Noise::kGaussian) {
    draw_normal(rng, out);
    return;
  }
  boost::random::uniform_real_distribution<double> uni(-std::sqrt(3.0), std::sqrt(3.0));
  for (Eigen::Index i = 0; i < out.size(); ++i) out(i) = uni(rng);
}

constexpr double kDivergence = 1e150;
constexpr double kPrecisionLimit = 1e10;

// The first periods of one run as the estimators saw them, replayed to time each estimator
// alone. Bounded: the replay's memory and time do not grow with the periods of a run.
constexpr std::size_t kReplayPeriods = 10000;
struct ReplayLog {
  std::vector<est::Packet> packets;
  std::vector<std::int64_t> packet_period;
  std::vector<Eigen::VectorXd> u, drive;  // per period
  std::size_t limit = kReplayPeriods;     // periods logged
};

class RunSimulation {
 public:
  RunSimulation(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace, ReplayLog* log)
      : sc_(sc),
        plant_(sc.model.plant),
        period_ns_(seconds_to_time(sc.run.period)),
        trace_(trace),
        log_(log),
        plant_handler_(this),
        sample_handler_(this),
        send_handler_(this),
        arrival_handler_(this),
        estimate_handler_(this),
        control_handler_(this),
        actuate_handler_(this),
        metrics_handler_(this) {
    const std::uint64_t seed = sc.run.seed;
    const Eigen::Index n = plant_.n();
    plant_rng_ = make_stream(seed, run, stream_id(StreamKind::kPlant, 0));
    input_rng_ = make_stream(seed, run, stream_id(StreamKind::kInput, 0));
    if (sc.mobility) mobility_ = sc.mobility->start(run);
    w_sqrt_ = models::psd_sqrt(plant_.W);
    w_.resize(plant_.nw());
    x_ = plant_.x0;
    next_x_.resize(n);
    u_ = Eigen::VectorXd::Zero(plant_.nu());
    u_applied_ = u_;
    u_prev_ = u_;
    drive_ = Eigen::VectorXd::Zero(n);
    recentre_ = Eigen::VectorXd::Zero(n);
    known_drive_ = Eigen::VectorXd::Zero(n);

    // Sensors and their noise streams.
    for (std::size_t s = 0; s < sc.model.sensors.size(); ++s) {
      const auto& spec = sc.model.sensors[s].spec;
      SensorState st;
      st.rng = make_stream(seed, run, stream_id(StreamKind::kSensor, s));
      st.r_sqrt = models::psd_sqrt(spec.R);
      st.noise.resize(spec.ny());
      st.stamps.assign(static_cast<std::size_t>(spec.buffer) + 1, 0);
      st.values = Eigen::MatrixXd::Zero(spec.ny(), spec.buffer + 1);
      if (spec.fresh_resend_noise) st.clean = Eigen::MatrixXd::Zero(spec.ny(), spec.buffer + 1);
      st.last_sent = Eigen::VectorXd::Zero(spec.ny());
      sensors_.push_back(std::move(st));
      true_output_.push_back(Eigen::VectorXd::Zero(spec.ny()));
      measured_.push_back(Eigen::VectorXd::Zero(spec.ny()));
      received_.push_back(Eigen::VectorXd::Zero(spec.ny()));
      received_stamp_.push_back(-1);
    }
    if (sc.input.controller) controller_ = sc.input.controller->instantiate();
    u_queue_.assign(static_cast<std::size_t>(sc.input.actuation_delay), Eigen::VectorXd::Zero(plant_.nu()));
    // Links: one fresh instance per run.
    for (std::size_t l = 0; l < sc.links.size(); ++l) {
      LinkState ls;
      ls.link = sc.links[l].link->clone();
      ls.rng = make_stream(seed, run, stream_id(StreamKind::kLink, l));
      ls.link->bind_run(mobility_.get(), seed, run);
      ls.link->reset(ls.rng);
      links_.push_back(std::move(ls));
    }
    // Actuator links and the mode process (jump_linear plant or actuator delivery patterns).
    if (!sc.model.actuators.empty()) {
      std::vector<const models::Link*> links;
      for (const auto& l : sc.links) links.push_back(l.link.get());
      std::vector<models::ActuatorSpec> specs;
      for (const auto& a : sc.model.actuators) specs.push_back(a.spec);
      actuators_ = std::make_unique<models::ActuatorStage>(specs, links, seed, run);
      u_applied_ = actuators_->applied();  // u0: held before the first delivery
    }
    mode_count_ = sc.model.mode_count();
    if (!plant_.modes.empty()) {
      mode_rng_ = make_stream(seed, run, stream_id(StreamKind::kPlant, 1));
      for (const auto& pm : plant_.modes) mode_w_sqrt_.push_back(models::psd_sqrt(pm.W));
    }
    // Estimators.
    int max_ext_blocks = 1;
    for (const auto& e : sc.estimators) {
      estimators_.push_back(e.design->instantiate());
      const auto ext = e.design->extended_size();
      if (ext > 0) max_ext_blocks = std::max<int>(max_ext_blocks, static_cast<int>(ext / n));
      EstimatorRunMetrics m;
      m.sse_state.assign(static_cast<std::size_t>(n), 0.0);
      if (mode_count_ > 0 && mode_count_ <= kMaxConfusionModes) {
        m.confusion.assign(static_cast<std::size_t>(mode_count_ * mode_count_), 0);
      }
      m.sensor_taken.assign(sc.model.sensors.size(), 0);
      m.sensor_sent.assign(sc.model.sensors.size(), 0);
      for (const auto& sm : sc.model.sensors) m.sensor_virtual_sse.emplace_back(static_cast<std::size_t>(sm.spec.ny()), 0.0);
      metrics_.push_back(std::move(m));
    }
    // True history x[k], x[k-1], ... (x[-j] = x0: the plant rests at x0 before t = 0).
    history_.assign(static_cast<std::size_t>(max_ext_blocks), plant_.x0);
    arrivals_.assign(sc.model.sensors.size(), 0);
    err_.resize(n);
  }

  RunMetrics execute() {
    const std::int64_t periods = sc_.run.periods;
    queue_.reserve(64);
    queue_.schedule(0, Phase::kPlant, &plant_handler_, 0);
    for (std::size_t s = 0; s < sensors_.size(); ++s) queue_.schedule(0, Phase::kSample, &sample_handler_, s);
    queue_.schedule(0, Phase::kEstimate, &estimate_handler_, 0);
    queue_.schedule(0, Phase::kControl, &control_handler_, 0);
    queue_.schedule(0, Phase::kActuate, &actuate_handler_, 0);
    queue_.schedule(0, Phase::kMetrics, &metrics_handler_, 0);
    queue_.run_until((periods - 1) * period_ns_);
    for (std::size_t e = 0; e < estimators_.size(); ++e) {
      metrics_[e].status = estimators_[e]->status();
      if (const auto* c = estimators_[e]->counters()) metrics_[e].counters = *c;
      if (precision_lost_ && metrics_[e].status == "ok") metrics_[e].status = "precision_lost";
    }
    return std::move(metrics_);
  }

 private:
  struct SensorState {
    Rng rng;
    Eigen::MatrixXd r_sqrt;
    Eigen::VectorXd noise;
    std::vector<std::int64_t> stamps;  // ring of the last buffer+1 samples (newest at head_)
    Eigen::MatrixXd values;            // column per ring slot
    Eigen::MatrixXd clean;             // C x of each slot (resend_noise = "fresh" only)
    int head = -1;
    int filled = 0;
    Eigen::VectorXd last_sent;  // send_on_delta: the value last sent
    bool has_sent = false;
  };
  struct LinkState {
    std::unique_ptr<models::Link> link;
    Rng rng;
  };

  std::int64_t period_of(SimTime t) const { return (t + period_ns_ - 1) / period_ns_; }
  bool reschedule(SimTime now, std::int64_t step, Phase phase, EventHandler* h, std::uint64_t arg) {
    const std::int64_t next = now / period_ns_ + step;
    if (next >= sc_.run.periods) return false;
    queue_.schedule(next * period_ns_, phase, h, arg);
    return true;
  }

  // Plant step: x[k] = A x[k-1] + Bu u_applied[k-1] + Bw w[k-1] (+ re-centring, known).
  void on_plant(SimTime now, std::uint64_t) {
    const std::int64_t k = now / period_ns_;
    if (mobility_) mobility_->advance(now);  // the kernel's clock drives the mobility (SUMO)
    if (sc_.plant_vehicle >= 0) {
      // The true state is the vehicle's longitudinal motion (position, speed[, acceleration]).
      const VehicleState& v = mobility_->vehicle(sc_.plant_vehicle);
      const double s[3] = {v.pos, v.speed, v.accel};
      for (Eigen::Index i = 0; i < x_.size() && i < 3; ++i) x_(i) = s[i];
      if (k > 0) {
        std::rotate(history_.rbegin(), history_.rbegin() + 1, history_.rend());
        history_.front() = x_;
      } else {
        std::fill(history_.begin(), history_.end(), x_);
      }
    } else if (k > 0) {
      draw_normal(plant_rng_, w_);
      if (sc_.recentre) recentre_.noalias() = -plant_.A * x_;  // deadbeat: known to every estimator
      if (!plant_.modes.empty()) {
        step_jump_plant(k);
      } else {
        w_ = w_sqrt_ * w_;
        sc_.disturbance.at(k - 1, w_);  // deterministic part of w[k-1]
        drive_.noalias() = plant_.Bu * u_applied_;
        drive_ += recentre_;
        next_x_.noalias() = plant_.A * x_;
        next_x_ += drive_;
        next_x_.noalias() += plant_.Bw * w_;
      }
      if (actuators_ || !plant_.modes.empty()) {
        // The estimators know what was sent (nominal Bu), not what was applied.
        known_drive_.noalias() = plant_.Bu * u_prev_;
        known_drive_ += recentre_;
      }
      if (actuators_) true_mode_ = actuated_mode_;
      x_.swap(next_x_);
      std::rotate(history_.rbegin(), history_.rbegin() + 1, history_.rend());
      history_.front() = x_;
    }
    reschedule(now, 1, Phase::kPlant, &plant_handler_, 0);
  }

  // x[k] = A_m x[k-1] + Bu_m u + Bw_m w with m = theta[k-1] drawn from the mode chain.
  void step_jump_plant(std::int64_t k) {
    const auto s = static_cast<Eigen::Index>(plant_.modes.size());
    boost::random::uniform_01<double> uniform;
    const double u = uniform(mode_rng_);
    double c = 0.0;
    int m = static_cast<int>(s) - 1;
    for (Eigen::Index i = 0; i < s; ++i) {
      c += k == 1 ? plant_.mode_initial(i) : plant_.mode_transition(true_mode_, i);
      if (u < c) {
        m = static_cast<int>(i);
        break;
      }
    }
    true_mode_ = m;
    const models::PlantMode& pm = plant_.modes[static_cast<std::size_t>(m)];
    drive_.noalias() = pm.Bu * u_applied_;
    drive_ += recentre_;
    next_x_.noalias() = pm.A * x_;
    next_x_ += drive_;
    w_ = mode_w_sqrt_[static_cast<std::size_t>(m)] * w_;
    sc_.disturbance.at(k - 1, w_);  // deterministic part of w[k-1]
    next_x_.noalias() += pm.Bw * w_;
  }

  void on_sample(SimTime now, std::uint64_t s) {
    const std::int64_t k = now / period_ns_;
    const auto& spec = sc_.model.sensors[s].spec;
    SensorState& st = sensors_[s];
    draw_sensor_noise(st.rng, spec.noise, st.noise);
    st.head = (st.head + 1) % (spec.buffer + 1);
    st.filled = std::min(st.filled + 1, spec.buffer + 1);
    st.stamps[static_cast<std::size_t>(st.head)] = k;
    st.values.col(st.head).noalias() = spec.C * x_;
    if (spec.fresh_resend_noise) st.clean.col(st.head) = st.values.col(st.head);
    st.values.col(st.head).noalias() += st.r_sqrt * st.noise;
    const auto sample = st.values.col(st.head);
    measured_[s] = sample;
    bool send = true;
    if (spec.policy == models::SensorSpec::Policy::kSendOnDelta) {
      // |y_i - y_i(last sent)| >= delta_i for some output i; the first sample is always sent.
      send = !st.has_sent || ((sample - st.last_sent).cwiseAbs().array() >= spec.delta.array()).any();
      if (send) {
        st.last_sent = sample;
        st.has_sent = true;
      }
    }
    if (k >= sc_.run.warmup) {
      for (auto& m : metrics_) {
        ++m.samples_taken;
        ++m.sensor_taken[s];
        if (send) ++m.sensor_sent[s];
        if (!send) {
          for (Eigen::Index i = 0; i < spec.ny(); ++i) {
            const double d = st.last_sent(i) - sample(i);
            m.sensor_virtual_sse[s][static_cast<std::size_t>(i)] += d * d;
          }
        }
      }
    }
    if (send) queue_.schedule(now, Phase::kSend, &send_handler_, s);
    reschedule(now, spec.every, Phase::kSample, &sample_handler_, s);
  }

  void on_send(SimTime now, std::uint64_t s) {
    const auto& spec = sc_.model.sensors[s].spec;
    const std::int64_t k = now / period_ns_;
    if (spec.link < 0) {
      deliver_copy(s, k, 0);
      return;
    }
    LinkState& ls = links_[static_cast<std::size_t>(spec.link)];
    ls.link->transmit_copies(ls.rng, delays_);
    const bool independent = ls.link->independent_copies();
    for (std::size_t c = 0; c < delays_.size(); ++c) {
      if (independent && c > 0) {  // the design model: every copy has its own noise
        SensorState& st = sensors_[s];
        draw_sensor_noise(st.rng, spec.noise, st.noise);
        st.values.col(st.head).noalias() = spec.C * x_;
        st.values.col(st.head).noalias() += st.r_sqrt * st.noise;
      }
      deliver_copy(s, k, delays_[c], independent);
    }
  }

  void deliver_copy(std::uint64_t s, std::int64_t k, std::int64_t delay, bool independent = false) {
    const auto& spec = sc_.model.sensors[s].spec;
    const std::int64_t arrival = k + delay;
    if (arrival >= sc_.run.periods) return;  // beyond the horizon
    std::size_t id;
    if (!free_.empty()) {
      id = free_.back();
      free_.pop_back();
    } else {
      id = pool_.size();
      pool_.emplace_back();
    }
    est::Packet& p = pool_[id];
    SensorState& st = sensors_[s];
    p.sensor = static_cast<int>(s);
    p.send_period = k;
    // A re-sent sample with a fresh noise draw is a new measurement, like an independent copy.
    p.independent_copy = independent || (spec.fresh_resend_noise && st.filled > 1);
    p.count = st.filled;
    p.stamps.resize(static_cast<std::size_t>(st.filled));
    p.values.resize(spec.ny() * st.filled);
    for (int i = 0; i < st.filled; ++i) {
      const int slot = (st.head - i + spec.buffer + 1) % (spec.buffer + 1);
      p.stamps[static_cast<std::size_t>(i)] = st.stamps[static_cast<std::size_t>(slot)];
      if (spec.fresh_resend_noise && i > 0) {  // resend_noise = "fresh": a new draw per re-send
        draw_normal(st.rng, st.noise);
        p.values.segment(i * spec.ny(), spec.ny()) = st.clean.col(slot);
        p.values.segment(i * spec.ny(), spec.ny()).noalias() += st.r_sqrt * st.noise;
      } else {
        p.values.segment(i * spec.ny(), spec.ny()) = st.values.col(slot);
      }
    }
    queue_.schedule(arrival * period_ns_, Phase::kArrival, &arrival_handler_, id);
  }

  void on_arrival(SimTime now, std::uint64_t id) {
    const std::int64_t k = period_of(now);
    const est::Packet& p = pool_[id];
    for (std::size_t e = 0; e < estimators_.size(); ++e) {
      const int used = estimators_[e]->on_packet(p, k);
      if (k >= sc_.run.warmup) metrics_[e].samples_used += used;
    }
    ++arrivals_[static_cast<std::size_t>(p.sensor)];
    const auto ps = static_cast<std::size_t>(p.sensor);
    if (p.count > 0 && p.stamps[0] > received_stamp_[ps]) {  // the newest sample seen at the controller node
      received_stamp_[ps] = p.stamps[0];
      received_[ps] = p.values.head(received_[ps].size());
    }
    if (log_ != nullptr && static_cast<std::size_t>(k) < log_->limit) {
      log_->packets.push_back(p);
      log_->packet_period.push_back(k);
    }
    free_.push_back(id);
  }

  void on_estimate(SimTime now, std::uint64_t) {
    const std::int64_t k = now / period_ns_;
    const est::PeriodInput in{u_prev_, actuators_ || !plant_.modes.empty() ? known_drive_ : drive_};
    for (auto& e : estimators_) e->on_period(k, in);
    if (log_ != nullptr && log_->u.size() < log_->limit) {
      log_->u.push_back(u_prev_);
      log_->drive.push_back(in.drive);
    }
    reschedule(now, 1, Phase::kEstimate, &estimate_handler_, 0);
  }

  void on_control(SimTime now, std::uint64_t) {
    using Kind = models::InputSpec::Kind;
    switch (sc_.input.kind) {
      case Kind::kNone: break;
      case Kind::kWhite: {
        draw_normal(input_rng_, u_);
        u_ = u_.cwiseProduct(sc_.input.std);
        break;
      }
      case Kind::kStateFeedback: {
        if (sc_.input.source_index < 0) {
          u_.noalias() = -sc_.input.K * x_;
        } else {
          u_.noalias() = -sc_.input.K * estimators_[static_cast<std::size_t>(sc_.input.source_index)]->state();
        }
        break;
      }
      case Kind::kController: {
        for (std::size_t s = 0; s < sensors_.size(); ++s) true_output_[s].noalias() = sc_.model.sensors[s].spec.C * x_;
        models::ControlContext ctx;
        ctx.k = now / period_ns_;
        ctx.period = sc_.run.period;
        ctx.t = static_cast<double>(ctx.k) * sc_.run.period;
        ctx.x = &x_;
        ctx.true_output = &true_output_;
        ctx.measured = &measured_;
        ctx.received = &received_;
        if (sc_.input.source_index >= 0) {
          estimate_ = estimators_[static_cast<std::size_t>(sc_.input.source_index)]->state();
          ctx.estimate = &estimate_;
        }
        controller_->compute(ctx, u_);
        reference_ = controller_->reference(ctx);
        break;
      }
    }
    reschedule(now, 1, Phase::kControl, &control_handler_, 0);
  }

  void on_actuate(SimTime now, std::uint64_t) {
    // After `actuation_delay` periods: x[k+1] uses u[k - actuation_delay] (zero before the first).
    Eigen::VectorXd& u_acting = u_queue_.empty() ? u_ : u_delayed_;
    if (!u_queue_.empty()) {
      u_delayed_ = u_queue_[u_head_];
      u_queue_[u_head_] = u_;
      u_head_ = (u_head_ + 1) % u_queue_.size();
    }
    if (actuators_) {
      actuated_mode_ = actuators_->actuate(u_acting);  // the plant applies what arrives
      u_applied_ = actuators_->applied();
    } else {
      u_applied_ = u_acting;
    }
    u_prev_ = u_acting;  // what the estimators know at the next update: what was sent to act now
    reschedule(now, 1, Phase::kActuate, &actuate_handler_, 0);
  }

  void on_metrics(SimTime now, std::uint64_t) {
    const std::int64_t k = now / period_ns_;
    const Eigen::Index n = plant_.n();
    if (trace_ != nullptr) {
      TraceRow row;
      row.period = k;
      row.x.assign(x_.data(), x_.data() + n);
      for (auto& e : estimators_) {
        const auto xh = e->state();
        row.xhat.emplace_back(xh.data(), xh.data() + n);
      }
      row.arrivals = arrivals_;
      row.mode = true_mode_;
      for (auto& e : estimators_) row.mode_hat.push_back(e->mode().value_or(-1));
      row.u.assign(u_.data(), u_.data() + u_.size());
      for (const auto& sm : sc_.model.sensors) {
        const Eigen::VectorXd y = sm.spec.C * x_;
        row.y.insert(row.y.end(), y.data(), y.data() + y.size());
      }
      row.reference = reference_;
      trace_->push_back(std::move(row));
    }
    std::fill(arrivals_.begin(), arrivals_.end(), 0);
    // |x| > 1e10: x - xhat has lost 10 of its 16 significant digits to rounding (an unstable
    // plant left without feedback or re-centring); the errors are no longer trustworthy.
    if (!precision_lost_ && x_.cwiseAbs().maxCoeff() > kPrecisionLimit) precision_lost_ = true;
    if (k >= sc_.run.warmup) {
      for (std::size_t e = 0; e < estimators_.size(); ++e) {
        EstimatorRunMetrics& m = metrics_[e];
        if (m.diverged) continue;
        err_ = x_ - estimators_[e]->state();
        const double e2 = err_.squaredNorm();
        double e2_ext = e2;
        if (const Eigen::VectorXd* xb = estimators_[e]->extended()) {
          for (Eigen::Index b = 1; b < xb->size() / n; ++b) {
            e2_ext += (history_[static_cast<std::size_t>(b)] - xb->segment(b * n, n)).squaredNorm();
          }
        }
        if (!std::isfinite(e2_ext) || e2_ext > kDivergence) {
          m.diverged = true;
          continue;
        }
        m.sse += e2;
        m.sse_ext += e2_ext;
        for (Eigen::Index i = 0; i < n; ++i) m.sse_state[static_cast<std::size_t>(i)] += err_(i) * err_(i);
        ++m.count;
      }
      score_modes(k);
    }
    reschedule(now, 1, Phase::kMetrics, &metrics_handler_, 0);
  }

  // Mode detection (Moayedi et al. eq. 27a-b): after the update of period k >= 1, each mode
  // estimator's estimate of theta[k-1] against the true one.
  void score_modes(std::int64_t k) {
    if (mode_count_ == 0 || k < 1 || true_mode_ < 0) return;
    for (std::size_t e = 0; e < estimators_.size(); ++e) {
      const std::optional<int> est = estimators_[e]->mode();
      if (!est) continue;
      EstimatorRunMetrics& m = metrics_[e];
      ++m.mode_count;
      if (*est != true_mode_) ++m.mode_errors;
      if (!m.confusion.empty() && *est >= 0 && *est < mode_count_) {
        ++m.confusion[static_cast<std::size_t>(true_mode_ * mode_count_ + *est)];
      }
    }
  }

  const Scenario& sc_;
  std::unique_ptr<MobilityRun> mobility_;  // before links_: links hold a pointer to it
  const models::LinearPlant& plant_;
  SimTime period_ns_;
  std::vector<TraceRow>* trace_;
  ReplayLog* log_;
  EventQueue queue_;
  MemberHandler<RunSimulation, &RunSimulation::on_plant> plant_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_sample> sample_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_send> send_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_arrival> arrival_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_estimate> estimate_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_control> control_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_actuate> actuate_handler_;
  MemberHandler<RunSimulation, &RunSimulation::on_metrics> metrics_handler_;

  Rng plant_rng_, input_rng_;
  Eigen::MatrixXd w_sqrt_;
  Eigen::VectorXd w_, x_, next_x_, u_, u_applied_, u_prev_, drive_, recentre_, err_, known_drive_;
  std::unique_ptr<models::ActuatorStage> actuators_;  // nullptr: ideal actuation
  Rng mode_rng_;                                       // jump_linear plant's mode chain
  std::vector<Eigen::MatrixXd> mode_w_sqrt_;
  int mode_count_ = 0;
  int actuated_mode_ = 0;  // delivery pattern of the last actuation
  int true_mode_ = -1;     // mode of the transition into the current period (theta[k-1])
  std::vector<Eigen::VectorXd> history_;
  std::vector<SensorState> sensors_;
  std::vector<LinkState> links_;
  std::vector<std::int64_t> delays_;
  std::vector<est::Packet> pool_;
  std::vector<std::size_t> free_;
  std::vector<int> arrivals_;
  std::vector<Eigen::VectorXd> true_output_, measured_, received_;
  std::vector<std::int64_t> received_stamp_;
  std::unique_ptr<models::Controller> controller_;
  Eigen::VectorXd estimate_;
  double reference_ = std::nan("");
  std::vector<Eigen::VectorXd> u_queue_;  // ring of the last actuation_delay inputs
  std::size_t u_head_ = 0;
  Eigen::VectorXd u_delayed_;             // the input that acts now when actuation_delay > 0
  std::vector<std::unique_ptr<est::Estimator>> estimators_;
  RunMetrics metrics_;
  bool precision_lost_ = false;
};

// Replays a logged run into a fresh instance of each estimator and times it alone: the median
// over repetitions of (wall time / periods). At least one repetition, at most 15, more only
// while the estimator's `budget` lasts.
std::vector<double> time_estimators(const Scenario& sc, const ReplayLog& log, std::chrono::nanoseconds budget) {
  std::vector<double> out;
  const std::size_t periods = log.u.size();
  for (const auto& entry : sc.estimators) {
    std::vector<double> samples;
    const auto begin = std::chrono::steady_clock::now();
    for (int rep = 0; rep < 15 && (rep < 1 || std::chrono::steady_clock::now() - begin < budget); ++rep) {
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

std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const auto t = static_cast<long>(s + 0.5);
  if (t >= 3600) return fmt::format("{}h{:02}m", t / 3600, (t / 60) % 60);
  if (t >= 60) return fmt::format("{}m{:02}s", t / 60, t % 60);
  return fmt::format("{}s", t);
}

}  // namespace

RunMetrics simulate_run(const Scenario& sc, std::uint64_t run, std::vector<TraceRow>* trace,
                        std::vector<double>* ns_per_period) {
  ReplayLog log;
  RunSimulation sim(sc, run, trace, ns_per_period != nullptr ? &log : nullptr);
  RunMetrics m = sim.execute();
  if (ns_per_period != nullptr) *ns_per_period = time_estimators(sc, log, std::chrono::milliseconds(200));
  return m;
}

CampaignResult run_campaign(const Scenario& sc, const CampaignOptions& options) {
  CampaignResult result;
  std::vector<std::uint64_t> todo;
  if (options.only_runs) {
    todo = *options.only_runs;
  } else {
    todo.resize(static_cast<std::size_t>(sc.run.runs));
    for (std::size_t r = 0; r < todo.size(); ++r) todo[r] = r;
  }
  const std::size_t runs = todo.size();
  const bool keep = !options.on_run;
  if (keep) {
    result.runs.resize(runs);
    if (options.only_runs) result.run_ids = todo;
  }
  int threads = options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::max(1, std::min<int>(threads, static_cast<int>(std::max<std::size_t>(runs, 1))));
  if (sc.mobility && sc.mobility->single_threaded()) threads = 1;  // one libsumo per process
  result.threads = threads;
  const auto start = std::chrono::steady_clock::now();

  // The first run simulated here is logged for the timing: at most kReplayPeriods periods and
  // at most 2 % of the periods this call simulates (at least 200), so that one replay of every
  // estimator costs about 2 % of the campaign.
  ReplayLog log;
  log.limit = std::min<std::size_t>(
      kReplayPeriods, std::max<std::size_t>(200, static_cast<std::size_t>(sc.run.periods) * runs / 50));
  std::atomic<std::size_t> next{0};
  std::atomic<std::size_t> done{0};
  std::exception_ptr error;
  std::mutex error_mutex, sink_mutex;
  std::atomic<bool> failed{false};
  std::vector<char> completed(keep ? runs : 0, 0);
  auto stop_requested = [&] { return options.stop != nullptr && options.stop->load() != 0; };
  auto worker = [&] {
    while (true) {
      if (stop_requested()) return;
      const std::size_t i = next.fetch_add(1);
      if (i >= runs) return;
      const std::uint64_t r = todo[i];
      try {
        ReplayLog* lg = i == 0 && options.time_estimators ? &log : nullptr;
        RunSimulation sim(sc, r, r == 0 && options.trace ? &result.trace : nullptr, lg);
        RunMetrics m = sim.execute();
        if (keep) {
          result.runs[i] = std::move(m);
          completed[i] = 1;
        } else {
          std::lock_guard<std::mutex> lock(sink_mutex);
          options.on_run(r, std::move(m));
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
        next = runs;
        return;
      }
      done.fetch_add(1);
    }
  };
  std::vector<std::thread> pool;
  try {
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  } catch (const std::system_error& e) {
    // Not an abort (a joinable std::thread destroyed): stop the workers started so far, then fail.
    next = runs;
    for (auto& t : pool) t.join();
    throw std::runtime_error(fmt::format("cannot start worker thread {} of {} ({}); retry with a smaller --threads",
                                         pool.size() + 2, threads, e.what()));
  }
  const bool any_progress = options.progress || options.progress_log;
  std::atomic<bool> finished{false};
  std::mutex progress_mutex;
  std::condition_variable progress_cv;
  std::thread progress;
  if (any_progress) {
    progress = std::thread([&] {
      const auto interval = options.progress ? std::chrono::milliseconds(200) : std::chrono::milliseconds(5000);
      std::unique_lock<std::mutex> lock(progress_mutex);
      while (!progress_cv.wait_for(lock, interval, [&] { return finished.load(); })) {
        const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const std::size_t d = done.load();
        const double rate = el > 0 ? static_cast<double>(d) / el : 0.0;
        const std::string eta = d > 0 ? format_duration(static_cast<double>(runs - d) / rate) : "?";
        if (options.progress) {
          std::fprintf(stderr, "\r%s run %zu/%zu  %.1f s  ETA %s   ", options.progress_label.c_str(), d, runs, el,
                       eta.c_str());
        } else {
          std::fprintf(stderr, "ncosim: %s%s%zu/%zu runs, %.2f runs/s, %.0f s elapsed, ETA %s\n",
                       options.progress_label.c_str(), options.progress_label.empty() ? "" : " ", d, runs, rate, el,
                       eta.c_str());
        }
        std::fflush(stderr);
      }
    });
  }
  worker();
  for (auto& t : pool) t.join();
  if (any_progress) {
    {
      std::lock_guard<std::mutex> lock(progress_mutex);
      finished = true;
    }
    progress_cv.notify_all();
    progress.join();
    if (options.progress) {
      std::fprintf(stderr, "\r%s %zu runs done in %.1f s      \n", options.progress_label.c_str(), done.load(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
  }
  if (error) std::rethrow_exception(error);
  result.runs_done = done.load();
  result.stopped = result.runs_done < runs;
  if (keep && result.stopped) {  // keep the completed runs only
    std::vector<RunMetrics> kept;
    std::vector<std::uint64_t> ids;
    for (std::size_t i = 0; i < runs; ++i) {
      if (completed[i] != 0) {
        kept.push_back(std::move(result.runs[i]));
        ids.push_back(todo[i]);
      }
    }
    result.runs = std::move(kept);
    result.run_ids = std::move(ids);
  }
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (options.time_estimators && !log.u.empty() && !stop_requested()) {
    // Timed alone, after the campaign, on a replay of the first run simulated (at most
    // kReplayPeriods periods; not part of the results' identity). Budget per estimator: 2 %
    // of the campaign's time, between 1 ms and 200 ms.
    const double share = 0.02 * result.wall_seconds / static_cast<double>(std::max<std::size_t>(sc.estimators.size(), 1));
    const auto budget = std::chrono::nanoseconds(static_cast<std::int64_t>(std::clamp(share, 0.001, 0.2) * 1e9));
    result.ns_per_period = time_estimators(sc, log, budget);
  } else {
    result.ns_per_period.assign(sc.estimators.size(), std::nan(""));
  }
  return result;
}

}  // namespace ncosim::sim
