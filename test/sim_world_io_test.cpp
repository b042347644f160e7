#include "multisession_mapper/sim/world_io.h"

#include <sstream>

#include <gtest/gtest.h>

#include "multisession_mapper/sim/campus_generator.h"

namespace multisession_mapper {
namespace sim {
namespace {

World SmallWorld() {
  CampusConfig config;
  config.profile = "small";
  config.seed = 3;
  config.num_sessions = 3;
  auto campus = GenerateCampus(config);
  EXPECT_TRUE(campus.ok()) << campus.status().message();
  return std::move(campus).value().world;
}

std::string ToText(const World& world) {
  std::ostringstream out;
  EXPECT_TRUE(WriteWorldYaml(out, world).ok());
  return out.str();
}

TEST(SimWorldIoTest, RoundTripKeepsEveryObject) {
  const World world = SmallWorld();
  const std::string text = ToText(world);
  auto read = ReadWorldYaml(text);
  ASSERT_TRUE(read.ok()) << read.status().message();
  const World& back = read.value();
  EXPECT_EQ(back.profile, world.profile);
  EXPECT_EQ(back.seed, world.seed);
  EXPECT_EQ(back.session_names, world.session_names);
  EXPECT_EQ(back.terrain.cols, world.terrain.cols);
  EXPECT_EQ(back.terrain.heights_m, world.terrain.heights_m);  // mm-quantised: exact
  EXPECT_EQ(back.terrain.materials, world.terrain.materials);
  ASSERT_EQ(back.objects.size(), world.objects.size());
  int moving = 0, with_parts = 0;
  for (std::size_t i = 0; i < world.objects.size(); ++i) {
    const WorldObject& a = world.objects[i];
    const WorldObject& b = back.objects[i];
    ASSERT_EQ(a.id, b.id);
    EXPECT_EQ(a.object_class, b.object_class);
    EXPECT_EQ(a.kind, b.kind);
    EXPECT_EQ(a.shape, b.shape);
    EXPECT_EQ(a.sessions_mask, b.sessions_mask) << "object " << a.id;
    EXPECT_LT((a.position_m - b.position_m).norm(), 1e-5);
    EXPECT_LT((a.size_m - b.size_m).norm(), 1e-5);
    EXPECT_NEAR(a.yaw_rad, b.yaw_rad, 1e-8);
    EXPECT_NEAR(a.pitch_rad, b.pitch_rad, 1e-8);
    EXPECT_NEAR(a.roll_rad, b.roll_rad, 1e-8);
    ASSERT_EQ(a.parts.size(), b.parts.size());
    for (std::size_t k = 0; k < a.parts.size(); ++k) {
      EXPECT_EQ(a.parts[k].shape, b.parts[k].shape);
      EXPECT_LT((a.parts[k].center_m - b.parts[k].center_m).norm(), 1e-5);
      EXPECT_LT((a.parts[k].size_m - b.parts[k].size_m).norm(), 1e-5);
      EXPECT_NEAR(a.parts[k].density_per_m, b.parts[k].density_per_m, 1e-6);
    }
    ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
    for (std::size_t k = 0; k < a.trajectory.size(); ++k) {
      EXPECT_NEAR(a.trajectory[k].stamp_s, b.trajectory[k].stamp_s, 1e-6);
      EXPECT_LT((a.trajectory[k].position_m - b.trajectory[k].position_m).norm(), 1e-5);
    }
    moving += a.moving();
    with_parts += !a.parts.empty();
  }
  EXPECT_GT(moving, 0);
  EXPECT_GT(with_parts, 100);
  // Writing what was read gives the same bytes.
  EXPECT_EQ(ToText(back), text);
}

TEST(SimWorldIoTest, FileRoundTrip) {
  const World world = SmallWorld();
  const std::string path = std::string(MSM_TEST_TMP_DIR) + "/sim_world_io_test_world.yaml";
  std::system((std::string("mkdir -p ") + MSM_TEST_TMP_DIR).c_str());
  ASSERT_TRUE(WriteWorldYamlFile(path, world).ok());
  auto read = ReadWorldYamlFile(path);
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(read.value().objects.size(), world.objects.size());
  EXPECT_FALSE(ReadWorldYamlFile(path + ".missing").ok());
}

TEST(SimWorldIoTest, ErrorsNameTheProblem) {
  const std::string header =
      "format: multisession_mapper_sim/1\nprofile: tiny\nseed: 1\nsessions: [s00, s01]\n"
      "terrain:\n  origin: [0, 0]\n  resolution_m: 1\n  cols: 2\n  rows: 2\n"
      "  heights:\n    - [0, 0]\n    - [0, 0]\n  materials:\n    - \"1\"\n";
  const std::string good_object =
      "objects:\n  - id: 4\n    class: parked_car\n    shape: box\n    pose: [1, 2, 0.75, 0]\n"
      "    size: [4.5, 1.8, 1.5]\n    sessions: [s01]\n";
  auto ok = ReadWorldYaml(header + good_object);
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_EQ(ok.value().objects[0].sessions_mask, 2u);

  auto bad_session = ReadWorldYaml(header + "objects:\n  - id: 4\n    class: parked_car\n"
                                   "    shape: box\n    pose: [1, 2, 0.75, 0]\n"
                                   "    size: [4.5, 1.8, 1.5]\n    sessions: [s07]\n");
  ASSERT_FALSE(bad_session.ok());
  EXPECT_NE(bad_session.status().message().find("s07"), std::string::npos);

  auto bad_class = ReadWorldYaml(header + "objects:\n  - id: 4\n    class: ufo\n    shape: box\n"
                                 "    pose: [1, 2, 0.75, 0]\n    size: [1, 1, 1]\n"
                                 "    sessions: [s00]\n");
  ASSERT_FALSE(bad_class.ok());
  EXPECT_NE(bad_class.status().message().find("ufo"), std::string::npos);

  auto missing_size = ReadWorldYaml(header + "objects:\n  - id: 4\n    class: pole\n"
                                    "    shape: box\n    pose: [1, 2, 0.75, 0]\n"
                                    "    sessions: [s00]\n");
  ASSERT_FALSE(missing_size.ok());
  EXPECT_NE(missing_size.status().message().find("size"), std::string::npos);
  EXPECT_FALSE(ReadWorldYaml("format: other/2\n").ok());
  EXPECT_FALSE(ReadWorldYaml("{{{").ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
