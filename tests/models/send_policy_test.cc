// tests/models/send_policy_test.cc — the built-in send policies, their readers, and the sensor
// process that asks them.
#include "models/send_policy.h"

#include <gtest/gtest.h>

#include <string>

#include "config/config.h"
#include "models/sensor.h"
#include "models/sensor_process.h"

namespace ncosim::models {
namespace {

SendPolicyRegistry policies() {
  SendPolicyRegistry r;
  register_send_policies(r);
  return r;
}

// Reads `text` as one [[sensor]] table of a 2-state plant.
SensorSpec read(const std::string& text) {
  const toml::table doc = toml::parse(text);
  const config::Table t(doc, "sensor[0]", "s.toml");
  LinearPlant plant;
  plant.A = Eigen::MatrixXd::Identity(2, 2);
  SensorSpec s = read_sensor(t, plant, {}, 0, policies());
  t.finish();
  return s;
}

std::string error_of(const std::string& text) {
  try {
    read(text);
  } catch (const config::ScenarioError& e) {
    return e.what();
  }
  return "";
}

TEST(SendPolicy, PeriodicIsTheDefaultAndSendsEverySample) {
  const SensorSpec s = read("C = [[1.0, 0.0]]\nR = [[0.01]]\n");
  EXPECT_EQ(s.policy->name(), "periodic");
  EXPECT_TRUE(s.policy->sends_every_sample());
  EXPECT_EQ(s.deadband(), nullptr);
  auto p = s.policy->instantiate();
  Eigen::VectorXd y(1);
  for (double v : {0.0, 0.0, 1e-9, -5.0}) {
    y(0) = v;
    EXPECT_TRUE(p->decide(y));
  }
  EXPECT_EQ(p->held(), nullptr);
}

TEST(SendPolicy, SendOnDeltaSendsTheFirstSampleThenOnlyMovesOfAtLeastDelta) {
  const SensorSpec s = read(
      "C = [[1.0, 0.0], [0.0, 1.0]]\nR = [[0.01, 0], [0, 0.01]]\npolicy = \"send_on_delta\"\ndelta "
      "= [0.5, 2.0]\n");
  EXPECT_EQ(s.policy->name(), "send_on_delta");
  EXPECT_FALSE(s.policy->sends_every_sample());
  ASSERT_NE(s.deadband(), nullptr);
  EXPECT_EQ(*s.deadband(), Eigen::Vector2d(0.5, 2.0));
  auto p = s.policy->instantiate();
  auto decide = [&](double a, double b) { return p->decide(Eigen::Vector2d(a, b)); };
  EXPECT_TRUE(decide(10.0, 10.0));   // the first sample
  EXPECT_FALSE(decide(10.4, 11.9));  // below both thresholds
  EXPECT_TRUE(decide(10.5, 10.0));   // output 1 moved by exactly delta_1 (inclusive)
  EXPECT_EQ(*p->held(), Eigen::Vector2d(10.5, 10.0));
  EXPECT_FALSE(decide(10.1, 11.9));  // compared with the last sent (10.5, 10), not the last sampled
  EXPECT_TRUE(decide(10.5, 12.0));   // output 2 moved by delta_2
  EXPECT_EQ(*p->held(), Eigen::Vector2d(10.5, 12.0));
}

TEST(SendPolicy, ReadersNameTheKeyAndTheValidValues) {
  EXPECT_NE(error_of("C = [[1.0, 0.0]]\nR = [[0.01]]\npolicy = \"send_on_delt\"\n")
                .find("did you mean \"send_on_delta\""),
            std::string::npos);
  EXPECT_NE(error_of("C = [[1.0, 0.0]]\nR = [[0.01]]\ndelta = 0.1\n")
                .find("expected no threshold with policy = \"periodic\""),
            std::string::npos);
  EXPECT_NE(error_of("C = [[1.0, 0.0]]\nR = [[0.01]]\npolicy = \"send_on_delta\"\ndelta = -0.1\n")
                .find("key 'sensor[0].delta'"),
            std::string::npos);
  // A range error says what it got, as written (issue 28).
  EXPECT_NE(error_of("C = [[1.0, 0.0]]\nR = [[0.01]]\npolicy = \"send_on_delta\"\ndelta = -0.1\n")
                .find("expected finite thresholds >= 0, got -0.1"),
            std::string::npos);
  EXPECT_NE(
      error_of(
          "C = [[1.0, 0.0]]\nR = [[0.01]]\npolicy = \"send_on_delta\"\ndelta = 0.1\nbuffer = 2\n")
          .find("expected buffer = 0 with policy = \"send_on_delta\""),
      std::string::npos);
  EXPECT_NE(error_of("C = [[1.0, 0.0]]\nR = [[0.01]]\npolicy = \"send_on_delta\"\n").find("delta"),
            std::string::npos);
}

TEST(SensorProcess, RingPacksTheNewestSamplesFirstWithTheirStamps) {
  SensorSpec s = read("C = [[1.0, 0.0]]\nR = [[0.0]]\nbuffer = 2\n");
  SensorProcess sensor(s, 0, 7, 3);
  Packet p;
  for (std::int64_t k = 0; k < 5; ++k) {
    EXPECT_TRUE(sensor.sample(k, Eigen::Vector2d(static_cast<double>(k), 0.0)));
    sensor.pack(p, k, false);
    ASSERT_EQ(p.count, std::min<int>(static_cast<int>(k) + 1, 3));
    for (int i = 0; i < p.count; ++i) {
      EXPECT_EQ(p.stamps[static_cast<std::size_t>(i)], k - i);
      EXPECT_EQ(p.values(i), static_cast<double>(k - i));  // R = 0: the samples are C x exactly
    }
    EXPECT_EQ(p.send_period, k);
    EXPECT_FALSE(p.independent_copy);
  }
}

TEST(SensorProcess, NoiseComesFromTheSensorsOwnStream) {
  SensorSpec s = read("C = [[1.0, 0.0]]\nR = [[1.0]]\n");
  SensorProcess a(s, 0, 7, 3), b(s, 0, 7, 3), other(s, 1, 7, 3);
  const Eigen::Vector2d x(0.0, 0.0);
  a.sample(0, x);
  b.sample(0, x);
  other.sample(0, x);
  EXPECT_EQ(a.newest()(0), b.newest()(0));      // same (seed, run, sensor): same draw
  EXPECT_NE(a.newest()(0), other.newest()(0));  // another sensor: another stream
}

}  // namespace
}  // namespace ncosim::models
