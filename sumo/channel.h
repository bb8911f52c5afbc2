// sumo/channel.h — the radio channel of the `sumo_distance` link: reception probability from
// distance, p(d) = P[received power >= threshold], and the medium-access delay law.
// Mean received power: tx power minus a piecewise log-distance path loss (one, two or three
// slopes; free space is one slope of exponent 2 from the Friis loss at 1 m). Fading: none,
// lognormal shadowing (sigma dB) or Nakagami-m on the power (integer m: closed form;
// real m: Boost.Math's regularised upper incomplete gamma), m possibly per distance bin.
// No interference model: every packet is judged alone (no collisions, no SINR from other
// transmitters); see scenarios/README.md.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/keys.h"

namespace ncosim::sumo {

inline constexpr double kSpeedOfLight = 299'792'458.0;

// L(d) = ref_loss + 10 n_0 log10(d/d_0) up to breakpoints[0], then slope n_1, ... (dB);
// L(d) = ref_loss for d <= d_0.
struct PathLoss {
  double ref_distance = 1.0;
  double ref_loss = 0.0;            // dB at ref_distance
  std::vector<double> breakpoints;  // ascending, > ref_distance
  std::vector<double> exponents;    // breakpoints.size() + 1
  double loss_db(double d) const;
};

struct Fading {
  enum class Kind { kNone, kLognormal, kNakagami };
  Kind kind = Kind::kNone;
  double sigma_db = 0.0;         // lognormal
  std::vector<double> m;         // nakagami shape per bin (m.size() = m_bounds.size() + 1)
  std::vector<double> m_bounds;  // bin upper edges (m): m[i] applies for d < m_bounds[i]
  double shape(double d) const;
};

// P[X >= threshold] for a Nakagami-m power X of mean `mean_mw` (both linear, same unit):
// the regularised upper incomplete gamma Q(m, m threshold / mean).
double nakagami_exceedance(double m, double threshold_over_mean);

struct DelayLaw {
  enum class Kind { k80211p, kCv2xMode4 };
  Kind kind = Kind::k80211p;
  // 802.11p (10 MHz channel, IEEE 802.11-2012 OFDM timing): AIFS = SIFS + aifsn x slot,
  // frame = 40 us preamble+SIGNAL + 8 us x ceil((16 + 8 size + 6) / (8 us x rate)), and with
  // `backoff` a uniform number of slots in 0..cw.
  double sifs = 32e-6, slot = 13e-6;
  int aifsn = 6, cw = 15;
  double rate = 6e6;  // bit/s
  int size = 300;     // bytes (MPDU)
  bool backoff = false;
  // C-V2X mode 4 (sensing-based semi-persistent scheduling): uniform in [t1, t2].
  double t1 = 0.001, t2 = 0.1;

  double frame_time() const;
  // Access delay (without propagation) from a uniform u in [0, 1).
  double sample(double u) const;
  // P[access delay <= x].
  double cdf(double x) const;
  std::string describe() const;
};

struct Channel {
  std::string preset;  // "" when fully custom
  double tx_power_dbm = 20.0;
  double threshold_dbm = -89.0;
  double frequency = 5.9e9;
  PathLoss path_loss;
  Fading fading;
  DelayLaw delay;

  double mean_rx_dbm(double d) const { return tx_power_dbm - path_loss.loss_db(d); }
  double reception_probability(double d) const;
  // P[delay in whole periods == j] for a packet sent over distance d (delay = access + d/c;
  // j = floor(delay / period)).
  double delay_period_probability(double d, double period, std::int64_t j) const;
  std::int64_t delay_periods(double d, double period, double u) const;
};

std::vector<std::string> preset_names();
std::string preset_help(const std::string& name);
Channel make_preset(const std::string& name);  // throws std::invalid_argument when unknown
// Friis free-space loss at distance d for wavelength c / frequency (dB).
double free_space_db(double d, double frequency);

// The channel's keys of a [[link]] table (the sumo_distance kind declares them after its own):
// `preset` then per-key overrides (tx_power, threshold, fading, sigma, m, m_bounds, mac, rate,
// size, aifsn, cw, backoff, t1, t2). The defaults of tx_power, threshold and the fading are the
// preset's; those of the delay law equal DelayLaw's initialisers (tests/sumo checks it).
const config::Keys& channel_keys();
// Reads them through channel_keys(). ScenarioError when bad.
Channel read_channel(const config::Table& t);

// `ncosim channel PRESET`: p(d) and the delay law as text or CSV, and a gnuplot script.
std::string channel_table(const Channel& ch, double max_distance, double step, bool csv);
std::string channel_gnuplot(const Channel& ch, const std::string& csv_file, const std::string& png);

// Counter-based draws keyed by (seed, run, sender, receiver, sequence number).
std::uint64_t stream_key(std::uint64_t seed, std::uint64_t run, std::uint64_t sender,
                         std::uint64_t receiver);
double keyed_uniform(std::uint64_t key, std::uint64_t seq, std::uint64_t draw);
std::uint64_t name_hash(const std::string& name);

}  // namespace ncosim::sumo
