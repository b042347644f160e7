#include "multisession_mapper/sim/campus_simulator.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "multisession_mapper/core/trajectory_io.h"

namespace multisession_mapper {
namespace sim {
namespace {

std::string Read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// Runs one session and returns a fingerprint of every sweep handed to the sink.
std::string RunOnce(int threads, const std::string& dir, SessionSummary* summary) {
  CampusSimulatorConfig config;
  config.campus.profile = "tiny";
  config.campus.seed = 12;
  config.campus.num_sessions = 2;
  config.num_threads = threads;
  config.max_scans_per_session = 12;
  auto sim = CampusSimulator::Create(config);
  EXPECT_TRUE(sim.ok()) << sim.status().message();
  std::system(("mkdir -p " + dir + "/truth").c_str());
  std::ostringstream fingerprint;
  int expected = 0;
  const core::Status status = sim.value().RunSession(
      1, dir,
      [&](int index, const SimulatedScan& scan) {
        EXPECT_EQ(index, expected++);  // in order
        fingerprint << index << ' ' << scan.scan.points.size() << ' ';
        for (const auto& p : scan.scan.points) fingerprint << p.position_m.x() << ',';
        return core::Status::Ok();
      },
      summary);
  EXPECT_TRUE(status.ok()) << status.message();
  EXPECT_TRUE(sim.value().WriteIndex(dir, {*summary}).ok());
  return fingerprint.str();
}

TEST(SimCampusSimulatorTest, ThreadsDoNotChangeTheOutput) {
  const std::string base = std::string(MSM_TEST_TMP_DIR) + "/sim_campus_simulator_test";
  SessionSummary one, three;
  const std::string a = RunOnce(1, base + "/t1", &one);
  const std::string b = RunOnce(3, base + "/t3", &three);
  EXPECT_EQ(a, b);
  EXPECT_EQ(one.scans, 12);
  EXPECT_EQ(one.name, "s01");
  EXPECT_NEAR(one.duration_s, 1.2, 1e-6);
  EXPECT_GT(one.points, 12u * 5000u);
  EXPECT_GT(one.label_points, 1000u);
  EXPECT_LT(one.label_points, one.points);
  for (const std::string f : {"/truth/s01.tum", "/truth/s01_labels.pcd", "/world.yaml",
                              "/sessions.yaml"}) {
    EXPECT_EQ(Read(base + "/t1" + f), Read(base + "/t3" + f)) << f;
  }
  auto tum = core::ReadTumFile(base + "/t1/truth/s01.tum");
  ASSERT_TRUE(tum.ok());
  ASSERT_EQ(tum.value().size(), 12u);
  EXPECT_NEAR(tum.value()[1].stamp_s - tum.value()[0].stamp_s, 0.1, 1e-6);
  EXPECT_NEAR(tum.value()[0].stamp_s, 1700000000.0 + 86400.0, 1e-6);
}

TEST(SimCampusSimulatorTest, SinkErrorStopsTheRun) {
  CampusSimulatorConfig config;
  config.campus.profile = "tiny";
  config.campus.num_sessions = 1;
  config.max_scans_per_session = 30;
  auto sim = CampusSimulator::Create(config);
  ASSERT_TRUE(sim.ok());
  int calls = 0;
  const core::Status status = sim.value().RunSession(
      0, std::string(MSM_TEST_TMP_DIR),
      [&](int index, const SimulatedScan&) {
        ++calls;
        return index == 3 ? core::Status::Error("disk full") : core::Status::Ok();
      },
      nullptr);
  EXPECT_FALSE(status.ok());
  EXPECT_EQ(status.message(), "disk full");
  EXPECT_EQ(calls, 4);
  CampusSimulatorConfig bad = config;
  bad.num_threads = 0;
  EXPECT_FALSE(CampusSimulator::Create(bad).ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
