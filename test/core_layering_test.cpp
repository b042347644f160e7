// The architecture rule of the package, as a test: the core and simulator libraries include no
// ROS header, so the algorithms can be used and tested without ROS.
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace {

std::vector<std::string> RosIncludesIn(const std::filesystem::path& dir) {
  static const std::regex kRosInclude(
      R"(^\s*#\s*include\s*[<"](ros|sensor_msgs|nodelet|tf2_ros|dynamic_reconfigure|pcl_ros|rosbag|geometry_msgs|nav_msgs|std_msgs)/)");
  std::vector<std::string> offenders;
  if (!std::filesystem::exists(dir)) return offenders;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::ifstream in(entry.path());
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
      ++number;
      if (std::regex_search(line, kRosInclude)) {
        offenders.push_back(entry.path().string() + ":" + std::to_string(number) + ": " + line);
      }
    }
  }
  return offenders;
}

TEST(CoreLayering, CoreAndSimulatorIncludeNoRosHeader) {
  const std::filesystem::path root(MSM_SOURCE_DIR);
  ASSERT_TRUE(std::filesystem::exists(root / "src/core")) << root;
  std::vector<std::string> offenders;
  for (const char* dir : {"include/multisession_mapper/core", "src/core",
                          "include/multisession_mapper/sim", "src/sim"}) {
    const auto found = RosIncludesIn(root / dir);
    offenders.insert(offenders.end(), found.begin(), found.end());
  }
  std::string report;
  for (const auto& o : offenders) report += o + "\n";
  EXPECT_TRUE(offenders.empty()) << "ROS includes in the core:\n" << report;
}

TEST(CoreLayering, DetectorFindsARosInclude) {
  // Guard against a regex that can never match: a file with a ROS include must be found.
  const std::filesystem::path dir =
      std::filesystem::path(MSM_TEST_TMP_DIR) / "core_layering_probe";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "probe.h") << "#include <ros/ros.h>\n";
  EXPECT_EQ(RosIncludesIn(dir).size(), 1u);
}

}  // namespace
