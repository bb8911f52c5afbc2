// sumo/channel.cc — path loss, fading, p(d), delay laws and the presets.
#include "sumo/channel.h"

#include <fmt/format.h>

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "kernel/rng.h"

namespace ncosim::sumo {

double PathLoss::loss_db(double d) const {
  if (!(d > ref_distance)) return ref_loss;
  double loss = ref_loss;
  double from = ref_distance;
  for (std::size_t i = 0; i < exponents.size(); ++i) {
    const double to = i < breakpoints.size() ? breakpoints[i] : INFINITY;
    const double upto = std::min(d, to);
    loss += 10.0 * exponents[i] * std::log10(upto / from);
    if (d <= to) break;
    from = to;
  }
  return loss;
}

double Fading::shape(double d) const {
  for (std::size_t i = 0; i < m_bounds.size(); ++i) {
    if (d < m_bounds[i]) return m[i];
  }
  return m.back();
}

double nakagami_exceedance(double m, double threshold_over_mean) {
  const double z = m * threshold_over_mean;
  if (m == std::floor(m) && m <= 64.0) {
    // Q(m, z) = e^{-z} sum_{i < m} z^i / i! for integer m.
    double term = 1.0, sum = 1.0;
    for (int i = 1; i < static_cast<int>(m); ++i) {
      term *= z / i;
      sum += term;
    }
    return std::exp(-z) * sum;
  }
  return boost::math::gamma_q(m, z);
}

double free_space_db(double d, double frequency) {
  const double lambda = kSpeedOfLight / frequency;
  return 20.0 * std::log10(4.0 * std::numbers::pi * d / lambda);
}

double Channel::reception_probability(double d) const {
  const double margin_db = threshold_dbm - mean_rx_dbm(d);  // threshold above the mean (dB)
  switch (fading.kind) {
    case Fading::Kind::kNone:
      return margin_db <= 0.0 ? 1.0 : 0.0;
    case Fading::Kind::kLognormal:
      if (fading.sigma_db == 0.0) return margin_db <= 0.0 ? 1.0 : 0.0;
      return 0.5 * std::erfc(margin_db / (fading.sigma_db * std::numbers::sqrt2));
    case Fading::Kind::kNakagami:
      return nakagami_exceedance(fading.shape(d), std::pow(10.0, margin_db / 10.0));
  }
  return 0.0;
}

double DelayLaw::frame_time() const {
  const double bits_per_symbol = rate * 8e-6;
  const double symbols = std::ceil((16.0 + 8.0 * size + 6.0) / bits_per_symbol);
  return 40e-6 + 8e-6 * symbols;
}

double DelayLaw::sample(double u) const {
  if (kind == Kind::kCv2xMode4) return t1 + u * (t2 - t1);
  double d = sifs + aifsn * slot + frame_time();
  if (backoff) d += std::floor(u * (cw + 1)) * slot;
  return d;
}

double DelayLaw::cdf(double x) const {
  if (kind == Kind::kCv2xMode4) {
    if (x < t1) return 0.0;
    if (x >= t2) return 1.0;
    return (x - t1) / (t2 - t1);
  }
  const double base = sifs + aifsn * slot + frame_time();
  if (!backoff) return x >= base ? 1.0 : 0.0;
  if (x < base) return 0.0;
  const double slots = std::floor((x - base) / slot) + 1.0;  // slots 0..slots-1 fit
  return std::min(1.0, slots / (cw + 1));
}

std::string DelayLaw::describe() const {
  if (kind == Kind::kCv2xMode4) {
    return fmt::format("C-V2X mode 4: access delay uniform in [{:g}, {:g}] ms, plus d/c", t1 * 1e3,
                       t2 * 1e3);
  }
  const double base = sifs + aifsn * slot + frame_time();
  std::string s = fmt::format(
      "802.11p (10 MHz): AIFS {:g} us (SIFS {:g} + {} x {:g} us slots) + frame {:g} us ({} bytes "
      "at {:g} Mbit/s)",
      (sifs + aifsn * slot) * 1e6, sifs * 1e6, aifsn, slot * 1e6, frame_time() * 1e6, size,
      rate * 1e-6);
  if (backoff) {
    s += fmt::format(" + backoff uniform in 0..{} slots (max {:g} us)", cw,
                     (base + cw * slot) * 1e6);
  } else {
    s += fmt::format(" = {:g} us", base * 1e6);
  }
  return s + ", plus d/c";
}

std::int64_t Channel::delay_periods(double d, double period, double u) const {
  return static_cast<std::int64_t>(std::floor((delay.sample(u) + d / kSpeedOfLight) / period));
}

double Channel::delay_period_probability(double d, double period, std::int64_t j) const {
  // delay periods == j  <=>  j T <= access + d/c < (j+1) T. The access-delay laws are
  // right-continuous step or continuous: P[a < x] = cdf(x - tiny) is approximated by the
  // continuous part; for the 802.11p steps, P[a < x] = cdf(prev(x)).
  const double prop = d / kSpeedOfLight;
  auto below = [&](double x) { return delay.cdf(std::nextafter(x - prop, -INFINITY)); };
  return below((j + 1) * period) - below(j * period);
}

namespace {

Channel veins() {
  Channel c;
  c.preset = "veins_nakagami3";
  c.frequency = 5.89e9;
  c.tx_power_dbm = 10.0 * std::log10(20.0);  // 20 mW
  c.threshold_dbm = -89.0;
  c.path_loss.ref_distance = 1.0;
  c.path_loss.ref_loss = free_space_db(1.0, c.frequency);
  c.path_loss.exponents = {2.0};
  c.fading.kind = Fading::Kind::kNakagami;
  c.fading.m = {3.0};
  return c;
}

Channel ns3() {
  Channel c;
  c.preset = "ns3_vanet";
  c.frequency = 5.9e9;
  c.tx_power_dbm = 20.0;
  c.threshold_dbm = -96.0;
  c.path_loss.ref_distance = 1.0;
  c.path_loss.ref_loss = 46.6777;
  c.path_loss.breakpoints = {200.0, 500.0};
  c.path_loss.exponents = {1.9, 3.8, 3.8};
  c.fading.kind = Fading::Kind::kNakagami;
  c.fading.m = {1.5, 0.75};
  c.fading.m_bounds = {80.0};
  return c;
}

Channel cheng() {
  Channel c;
  c.preset = "cheng2007";
  c.frequency = 5.9e9;
  c.tx_power_dbm = 20.0;
  c.threshold_dbm = -89.0;
  c.path_loss.ref_distance = 1.0;
  c.path_loss.ref_loss = free_space_db(1.0, c.frequency);
  // Defaults of Artery's VanetNakagamiFading (riebl/artery, src/artery/inet/VanetNakagamiFading.ned
  // and .cc): gamma1 = 2, gamma2 = 4, criticalDistance = 100 m, free-space reference loss at 1 m,
  // shape factors per distance bin. Its lognormal terms (sigma1 5.6 dB, sigma2 8.1 dB) are not
  // modelled here. See scenarios/README.md.
  c.path_loss.breakpoints = {100.0};
  c.path_loss.exponents = {2.0, 4.0};
  c.fading.kind = Fading::Kind::kNakagami;
  c.fading.m = {3.01, 1.18, 1.94, 1.86, 0.45, 0.32};
  c.fading.m_bounds = {4.7, 11.7, 28.9, 71.6, 177.3};
  return c;
}

}  // namespace

std::vector<std::string> preset_names() { return {"veins_nakagami3", "ns3_vanet", "cheng2007"}; }

std::string preset_help(const std::string& name) {
  if (name == "veins_nakagami3") {
    return "free space (Friis, 5.89 GHz) + Nakagami m = 3, 20 mW, -89 dBm "
           "(Killat & Hartenstein 2009 closed form)";
  }
  if (name == "ns3_vanet") {
    return "ns-3 ThreeLogDistance (1/200/500 m, 1.9/3.8/3.8, 46.6777 dB) + Nakagami m = 1.5 "
           "(< 80 m) / 0.75, 20 dBm, -96 dBm";
  }
  if (name == "cheng2007") {
    return "Cheng et al. 2007 dual slope (2 / 4, break 100 m) + Nakagami m binned by distance "
           "(Artery VanetNakagamiFading defaults, without its lognormal term), 20 dBm, -89 dBm";
  }
  return "";
}

Channel make_preset(const std::string& name) {
  if (name == "veins_nakagami3") return veins();
  if (name == "ns3_vanet") return ns3();
  if (name == "cheng2007") return cheng();
  throw std::invalid_argument(name);
}

using config::Key;

const config::Keys& channel_keys() {
  static const config::Keys keys{
      Key::choice("preset", preset_names())
          .or_default("veins_nakagami3")
          .help("the channel preset (below); the keys below override its values"),
      Key::number("tx_power")
          .optional("preset")
          .unit("dBm")
          .help("transmit power (antenna gains included), finite"),
      Key::number("threshold")
          .optional("preset")
          .unit("dBm")
          .help("reception threshold (sensitivity), finite"),
      Key::choice("fading", {"none", "lognormal", "nakagami"})
          .optional("preset")
          .help("fading on the received power; setting it drops the preset's fading"),
      Key::number("sigma")
          .range(0.0, 100.0)
          .says("a standard deviation in dB in [0, 100]")
          .optional("required with lognormal")
          .unit("dB")
          .help("shadowing standard deviation, 0 .. 100: p = 1/2 erfc((threshold - mean) / "
                "(sigma sqrt(2)))"),
      // The received power is Gamma(m, mean/m) for any m > 0. The textbook Nakagami-m model has
      // m >= 0.5, but measured fits go below it (Artery's defaults for Cheng et al.: 0.45, 0.32).
      Key::numbers("m")
          .above(0.0)
          .max(1000.0)
          .says("Nakagami shapes in (0, 1000]")
          .optional("preset (required with fading = \"nakagami\")")
          .help("Nakagami shape per distance bin, each in (0, 1000]: p = Q(m, m threshold / "
                "mean), the regularised upper incomplete gamma"),
      Key::numbers("m_bounds")
          .optional("none")
          .unit("m")
          .help("bin edges, increasing, > 0, one fewer than m: m[i] applies for d < "
                "m_bounds[i], the last beyond"),
      Key::choice("mac", {"80211p", "cv2x_mode4"}).or_default("80211p").help("delay law"),
      Key::number("rate")
          .range(1.0, 54.0)
          .says("a rate in Mbit/s in [1, 54]")
          .or_default(6.0)
          .unit("Mbit/s")
          .help("802.11p data rate, 1 .. 54"),
      Key::integer("size")
          .range(1, 65535)
          .says("a frame size in bytes in 1..65535")
          .or_default(300)
          .unit("bytes")
          .help("802.11p frame (MPDU) size, 1 .. 65535"),
      Key::integer("aifsn").range(1, 15).or_default(6).help("802.11p AIFSN (6: AC_BE), 1 .. 15"),
      Key::integer("cw").range(0, 1023).or_default(15).help(
          "802.11p contention window (backoff slots 0 .. cw), 0 .. 1023"),
      Key::boolean("backoff").or_default(false).help("add a uniform backoff of 0 .. cw slots"),
      Key::number("t1")
          .range(0.0, 1.0)
          .says("seconds in [0, 1]")
          .or_default(0.001)
          .unit("s")
          .help("C-V2X mode 4: access delay uniform in [t1, t2] (the SB-SPS selection window); 0 "
                "<= t1 < t2"),
      Key::number("t2")
          .max(10.0)
          .says("seconds in (t1, 10]")
          .or_default(0.1)
          .unit("s")
          .help("C-V2X mode 4: t1 < t2 <= 10"),
  };
  return keys;
}

namespace {

// fading, sigma, m, m_bounds over the preset's fading.
void read_fading(const config::KeyReader& t, Fading& fading) {
  if (const auto f = t.opt_string("fading")) {
    fading = Fading{};
    if (*f == "lognormal") {
      fading.kind = Fading::Kind::kLognormal;
      fading.sigma_db = t.number("sigma");
    } else if (*f == "nakagami") {
      fading.kind = Fading::Kind::kNakagami;
      fading.m = t.numbers("m");
    }
  }
  if (fading.kind != Fading::Kind::kNakagami) return;
  if (t.has("m")) {
    if (!t.has("fading")) fading.m = t.numbers("m");
    fading.m_bounds = t.has("m_bounds") ? t.numbers("m_bounds") : std::vector<double>{};
  }
  if (fading.m.empty()) t.fail("m", "expected at least one Nakagami shape");
  if (fading.m_bounds.size() + 1 != fading.m.size()) {
    t.fail("m_bounds", fmt::format("expected {} bin edges for {} shapes, got {}",
                                   fading.m.size() - 1, fading.m.size(), fading.m_bounds.size()));
  }
  for (std::size_t i = 0; i < fading.m_bounds.size(); ++i) {
    if (!(fading.m_bounds[i] > 0.0) || (i > 0 && fading.m_bounds[i] <= fading.m_bounds[i - 1])) {
      t.fail("m_bounds", fmt::format("expected increasing positive distances (m), got {}",
                                     fmt::join(fading.m_bounds, ", ")));
    }
  }
}

// mac and its law's keys (only those of the chosen law are read).
void read_delay(const config::KeyReader& t, DelayLaw& d) {
  if (t.string("mac") == "80211p") {
    d.kind = DelayLaw::Kind::k80211p;
    d.rate = t.number("rate") * 1e6;
    d.size = static_cast<int>(t.integer("size"));
    d.aifsn = static_cast<int>(t.integer("aifsn"));
    d.cw = static_cast<int>(t.integer("cw"));
    d.backoff = t.boolean("backoff");
  } else {
    d.kind = DelayLaw::Kind::kCv2xMode4;
    d.t1 = t.number("t1");
    d.t2 = t.number("t2");
    if (!(d.t2 > d.t1)) t.fail("t2", fmt::format("expected seconds in (t1, 10], got {}", d.t2));
  }
}

}  // namespace

Channel read_channel(const config::Table& table) {
  const config::KeyReader t(table, channel_keys());
  Channel c = make_preset(t.string("preset"));
  // Table::number refuses inf and nan: a given power is finite.
  c.tx_power_dbm = t.opt_number("tx_power").value_or(c.tx_power_dbm);
  c.threshold_dbm = t.opt_number("threshold").value_or(c.threshold_dbm);
  read_fading(t, c.fading);
  read_delay(t, c.delay);
  return c;
}

std::string channel_table(const Channel& ch, double max_distance, double step, bool csv) {
  std::string out;
  if (csv) {
    out += "distance_m,mean_rx_dbm,p_reception\n";
  } else {
    out += fmt::format("channel {}: tx {:g} dBm, threshold {:g} dBm\n", ch.preset, ch.tx_power_dbm,
                       ch.threshold_dbm);
    out += fmt::format("delay: {}\n", ch.delay.describe());
    out += "no interference model: every packet is judged alone (no collisions, no SINR)\n";
    out += fmt::format("{:>10} {:>12} {:>12}\n", "d (m)", "Pr (dBm)", "p(d)");
  }
  const auto n = static_cast<int>(std::floor(max_distance / step + 1e-9));
  for (int i = 0; i <= n; ++i) {
    const double d = std::max(1.0, i * step);
    if (csv) {
      out += fmt::format("{},{:.6f},{:.9g}\n", d, ch.mean_rx_dbm(d), ch.reception_probability(d));
    } else {
      out += fmt::format("{:>10g} {:>12.2f} {:>12.6f}\n", d, ch.mean_rx_dbm(d),
                         ch.reception_probability(d));
    }
  }
  return out;
}

std::string channel_gnuplot(const Channel& ch, const std::string& csv_file,
                            const std::string& png) {
  return fmt::format(
      "# p(d) of channel preset {0}: ncosim channel {0} --csv > {1}; gnuplot this script\n"
      "set terminal pngcairo size 800,500\nset output '{2}'\nset datafile separator ','\n"
      "set xlabel 'distance (m)'\nset ylabel 'reception probability p(d)'\nset yrange "
      "[0:1.05]\nset grid\n"
      "plot '{1}' using 1:3 skip 1 with lines lw 2 title '{0}'\n",
      ch.preset, csv_file, png);
}

std::uint64_t name_hash(const std::string& name) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : name) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::uint64_t stream_key(std::uint64_t seed, std::uint64_t run, std::uint64_t sender,
                         std::uint64_t receiver) {
  using kernel::splitmix64;
  return splitmix64(splitmix64(splitmix64(splitmix64(seed) ^ run) ^ sender) ^ receiver);
}

double keyed_uniform(std::uint64_t key, std::uint64_t seq, std::uint64_t draw) {
  using kernel::splitmix64;
  const std::uint64_t z = splitmix64(splitmix64(key ^ splitmix64(seq)) ^ draw);
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

}  // namespace ncosim::sumo
