#include "dynamic_points_display.h"

#include <cmath>
#include <stdexcept>

#include <OgreSceneManager.h>
#include <OgreSceneNode.h>

#include <rviz/display_context.h>
#include <rviz/frame_manager.h>
#include <rviz/properties/bool_property.h>
#include <rviz/properties/color_property.h>
#include <rviz/properties/float_property.h>
#include <rviz/properties/int_property.h>
#include <rviz/properties/status_property.h>
#include <sensor_msgs/point_cloud2_iterator.h>

namespace multisession_mapper {
namespace rviz_plugins {
namespace {

// Finite x/y/z of `cloud`; an empty cloud (also one without fields) gives no point.
// Throws std::runtime_error when a non-empty cloud lacks float x, y or z fields.
std::vector<Ogre::Vector3> FinitePoints(const sensor_msgs::PointCloud2& cloud) {
  std::vector<Ogre::Vector3> points;
  const size_t n = static_cast<size_t>(cloud.width) * cloud.height;
  if (n == 0) return points;
  if (cloud.data.size() < n * cloud.point_step) {
    throw std::runtime_error("data is shorter than width * height * point_step");
  }
  points.reserve(n);
  sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  for (size_t i = 0; i < n; ++i, ++x, ++y, ++z) {
    if (std::isfinite(*x) && std::isfinite(*y) && std::isfinite(*z)) {
      points.emplace_back(*x, *y, *z);
    }
  }
  return points;
}

void Fill(rviz::PointCloud& cloud, const std::vector<Ogre::Vector3>& positions,
          const Ogre::ColourValue& color, float size_m) {
  cloud.clear();
  cloud.setRenderMode(rviz::PointCloud::RM_FLAT_SQUARES);
  cloud.setDimensions(size_m, size_m, size_m);
  std::vector<rviz::PointCloud::Point> points(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    points[i].position = positions[i];
    points[i].color = color;
  }
  if (!points.empty()) cloud.addPoints(points.data(), static_cast<uint32_t>(points.size()));
}

}  // namespace

DynamicPointsDisplay::DynamicPointsDisplay() {
  removed_color_property_ = new rviz::ColorProperty(
      "Removed Color", QColor(255, 0, 0), "Colour of the dynamic points removed from the map.",
      this, SLOT(updateStyle()));
  mended_color_property_ = new rviz::ColorProperty(
      "Mended Color", QColor(0, 200, 255),
      "Colour of the current-session points added behind removed objects.", this,
      SLOT(updateStyle()));
  show_mended_property_ = new rviz::BoolProperty(
      "Show Mended", true, "Draw the mended points as well as the removed ones.", this,
      SLOT(updateStyle()));
  held_color_property_ = new rviz::ColorProperty(
      "Held Color", QColor(130, 60, 255),
      "Colour of the new-session points of new objects that the merge did not add.", this,
      SLOT(updateStyle()));
  show_held_property_ = new rviz::BoolProperty(
      "Show Held", true, "Draw the held-back points of new objects.", this,
      SLOT(updateStyle()));
  point_size_property_ = new rviz::FloatProperty(
      "Point Size", 0.15f, "Side of the square drawn per point [m].", this, SLOT(updateStyle()));
  point_size_property_->setMin(0.001f);
  history_length_property_ = new rviz::IntProperty(
      "History Length", 50,
      "Number of DynamicPoints messages kept on screen (one per history/current submap pair).",
      this, SLOT(updateHistoryLength()));
  history_length_property_->setMin(1);
  history_length_property_->setMax(100000);
}

DynamicPointsDisplay::~DynamicPointsDisplay() {
  if (initialized()) {
    for (Visual& v : visuals_) destroyVisual(v);
  }
}

void DynamicPointsDisplay::reset() {
  MFDClass::reset();
  for (Visual& v : visuals_) destroyVisual(v);
  visuals_.clear();
}

void DynamicPointsDisplay::destroyVisual(Visual& visual) {
  visual.removed_cloud.reset();  // MovableObjects detach themselves from the node
  visual.mended_cloud.reset();
  visual.held_cloud.reset();
  if (visual.node != nullptr) scene_manager_->destroySceneNode(visual.node);
  visual.node = nullptr;
}

void DynamicPointsDisplay::fillClouds(Visual& visual) const {
  const float size = point_size_property_->getFloat();
  Fill(*visual.removed_cloud, visual.removed, removed_color_property_->getOgreColor(), size);
  Fill(*visual.mended_cloud, visual.mended, mended_color_property_->getOgreColor(), size);
  visual.mended_cloud->setVisible(show_mended_property_->getBool());
  Fill(*visual.held_cloud, visual.held, held_color_property_->getOgreColor(), size);
  visual.held_cloud->setVisible(show_held_property_->getBool());
}

void DynamicPointsDisplay::processMessage(const DynamicPoints::ConstPtr& msg) {
  Ogre::Vector3 position;
  Ogre::Quaternion orientation;
  if (!context_->getFrameManager()->getTransform(msg->header, position, orientation)) {
    setStatus(rviz::StatusProperty::Error, "Transform",
              "No transform from [" + QString::fromStdString(msg->header.frame_id) + "] to [" +
                  fixed_frame_ + "]");
    return;
  }
  deleteStatus("Transform");

  Visual visual;
  try {
    visual.removed = FinitePoints(msg->removed);
    visual.mended = FinitePoints(msg->mended);
    visual.held = FinitePoints(msg->held);
  } catch (const std::exception& e) {
    setStatus(rviz::StatusProperty::Error, "Message", QString("Unreadable cloud: ") + e.what());
    return;
  }
  visual.node = scene_node_->createChildSceneNode(position, orientation);
  visual.removed_cloud = std::make_unique<rviz::PointCloud>();
  visual.mended_cloud = std::make_unique<rviz::PointCloud>();
  visual.held_cloud = std::make_unique<rviz::PointCloud>();
  // Ogre refuses two objects of the same name on one node: name them after the message.
  const std::string name = "msm_dynamic_points_" + std::to_string(num_visuals_created_++);
  visual.removed_cloud->setName(name + "_removed");
  visual.mended_cloud->setName(name + "_mended");
  visual.held_cloud->setName(name + "_held");
  visual.node->attachObject(visual.removed_cloud.get());
  visual.node->attachObject(visual.mended_cloud.get());
  visual.node->attachObject(visual.held_cloud.get());
  fillClouds(visual);
  setStatus(rviz::StatusProperty::Ok, "Message",
            QString("%1:%2 by %3:%4: %5 removed, %6 mended, %7 held back")
                .arg(QString::fromStdString(msg->history_session)).arg(msg->history_submap)
                .arg(QString::fromStdString(msg->current_session)).arg(msg->current_submap)
                .arg(visual.removed.size()).arg(visual.mended.size()).arg(visual.held.size()));
  visuals_.push_back(std::move(visual));
  trimHistory();
  context_->queueRender();
}

void DynamicPointsDisplay::trimHistory() {
  const size_t keep = static_cast<size_t>(std::max(1, history_length_property_->getInt()));
  while (visuals_.size() > keep) {
    destroyVisual(visuals_.front());
    visuals_.pop_front();
  }
}

void DynamicPointsDisplay::updateStyle() {
  for (Visual& v : visuals_) fillClouds(v);
  context_->queueRender();
}

void DynamicPointsDisplay::updateHistoryLength() {
  trimHistory();
  context_->queueRender();
}

}  // namespace rviz_plugins
}  // namespace multisession_mapper

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(multisession_mapper::rviz_plugins::DynamicPointsDisplay, rviz::Display)
