#include "multisession_mapper/core/trajectory_io.h"

#include <filesystem>
#include <sstream>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

Trajectory MakeTrajectory() {
  Trajectory t;
  for (int i = 0; i < 10; ++i) {
    StampedPose sp;
    sp.stamp_s = 1700000000.0 + 0.1 * i;
    sp.pose = se3::FromXyzRpy(i * 1.5, -i * 0.25, 0.01 * i, 0.01 * i, -0.02 * i, 0.3 * i);
    t.push_back(sp);
  }
  return t;
}

TEST(TrajectoryIo, RoundTripThroughStream) {
  const Trajectory in = MakeTrajectory();
  std::stringstream buffer;
  ASSERT_TRUE(WriteTum(buffer, in).ok());
  StatusOr<Trajectory> out = ReadTum(buffer);
  ASSERT_TRUE(out.ok()) << out.status().message();
  ASSERT_EQ(out.value().size(), in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    EXPECT_NEAR(out.value()[i].stamp_s, in[i].stamp_s, 1e-9);
    EXPECT_TRUE(out.value()[i].pose.isApprox(in[i].pose, 1e-6));
  }
}

TEST(TrajectoryIo, RoundTripThroughFile) {
  std::filesystem::create_directories(MSM_TEST_TMP_DIR);
  const std::string path = std::string(MSM_TEST_TMP_DIR) + "/trajectory_io_test.tum";
  const Trajectory in = MakeTrajectory();
  ASSERT_TRUE(WriteTumFile(path, in).ok());
  StatusOr<Trajectory> out = ReadTumFile(path);
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_EQ(out.value().size(), in.size());
}

TEST(TrajectoryIo, SkipsCommentsAndBlankLines) {
  std::istringstream in("# header\n\n1.0 0 0 0 0 0 0 1\n  # another\n2.0 1 0 0 0 0 0 1\n");
  StatusOr<Trajectory> out = ReadTum(in);
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_EQ(out.value().size(), 2u);
}

TEST(TrajectoryIo, MalformedLineNamesTheLine) {
  std::istringstream in("1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0\n");
  StatusOr<Trajectory> out = ReadTum(in, "traj.tum");
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("traj.tum:2"), std::string::npos)
      << out.status().message();
}

TEST(TrajectoryIo, RejectsNonFiniteZeroQuaternionAndBackwardStamps) {
  std::istringstream nan_in("1.0 nan 0 0 0 0 0 1\n");
  EXPECT_FALSE(ReadTum(nan_in).ok());
  std::istringstream zero_q("1.0 0 0 0 0 0 0 0\n");
  EXPECT_FALSE(ReadTum(zero_q).ok());
  std::istringstream backwards("2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  EXPECT_FALSE(ReadTum(backwards).ok());
  std::istringstream extra("1.0 0 0 0 0 0 0 1 5\n");
  EXPECT_FALSE(ReadTum(extra).ok());
}

TEST(TrajectoryIo, MissingFileIsAnError) {
  StatusOr<Trajectory> out = ReadTumFile("/nonexistent/dir/none.tum");
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("none.tum"), std::string::npos);
}

TEST(TrajectoryIo, WriteRejectsInvalidPose) {
  Trajectory t = MakeTrajectory();
  t[3].pose.translation().x() = std::nan("");
  std::stringstream buffer;
  EXPECT_FALSE(WriteTum(buffer, t).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
