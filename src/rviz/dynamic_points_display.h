// RViz display of multisession_mapper/DynamicPoints: the points removed from a history submap
// by low-dynamic detection (Ding et al., Sec. III-D) in red, and the current-session points
// mended in behind them in another colour, and the points of new objects that a merge held back
// (not added) in a third. The last `History Length` messages stay visible (one
// message per history/current submap pair), so a whole merge can be inspected at once.
#pragma once

#ifndef Q_MOC_RUN
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include <multisession_mapper/DynamicPoints.h>
#include <rviz/message_filter_display.h>
#include <rviz/ogre_helpers/point_cloud.h>
#endif

namespace Ogre {
class SceneNode;
}
namespace rviz {
class BoolProperty;
class ColorProperty;
class FloatProperty;
class IntProperty;
}  // namespace rviz

namespace multisession_mapper {
namespace rviz_plugins {

class DynamicPointsDisplay
    : public rviz::MessageFilterDisplay<multisession_mapper::DynamicPoints> {
  Q_OBJECT

 public:
  DynamicPointsDisplay();
  ~DynamicPointsDisplay() override;

  void reset() override;

 private Q_SLOTS:
  void updateStyle();          // colours, point size, visibility of mended points
  void updateHistoryLength();

 private:
  // One received message: its two clouds, positioned in the fixed frame by `node`.
  struct Visual {
    Ogre::SceneNode* node = nullptr;
    std::vector<Ogre::Vector3> removed, mended, held;  // message frame [m], finite points only
    std::unique_ptr<rviz::PointCloud> removed_cloud, mended_cloud, held_cloud;
  };

  void processMessage(const DynamicPoints::ConstPtr& msg) override;
  void fillClouds(Visual& visual) const;
  void destroyVisual(Visual& visual);
  void trimHistory();

  rviz::ColorProperty* removed_color_property_ = nullptr;
  rviz::ColorProperty* mended_color_property_ = nullptr;
  rviz::BoolProperty* show_mended_property_ = nullptr;
  rviz::ColorProperty* held_color_property_ = nullptr;
  rviz::BoolProperty* show_held_property_ = nullptr;
  rviz::FloatProperty* point_size_property_ = nullptr;  // [m]
  rviz::IntProperty* history_length_property_ = nullptr;

  std::deque<Visual> visuals_;  // oldest first
  uint64_t num_visuals_created_ = 0;
};

}  // namespace rviz_plugins
}  // namespace multisession_mapper
