#include "loop_candidates_display.h"

#include <algorithm>

#include <OgreSceneManager.h>
#include <OgreSceneNode.h>

#include <rviz/display_context.h>
#include <rviz/frame_manager.h>
#include <rviz/ogre_helpers/billboard_line.h>
#include <rviz/ogre_helpers/movable_text.h>
#include <rviz/ogre_helpers/shape.h>
#include <rviz/properties/bool_property.h>
#include <rviz/properties/color_property.h>
#include <rviz/properties/float_property.h>
#include <rviz/properties/status_property.h>

#include "loop_candidate_visuals.h"

namespace multisession_mapper {
namespace rviz_plugins {
namespace {

Ogre::Vector3 ToOgre(const geometry_msgs::Point& p) {
  return Ogre::Vector3(static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z));
}

struct StatusStyle {
  const char* name;
  QColor color;
  bool shown;
};

// Index = LoopCandidate::status.
const StatusStyle kStatusStyles[kNumLoopStatuses] = {
    {"Candidate", QColor(255, 210, 0), true},
    {"Accepted", QColor(0, 210, 90), true},
    {"Rejected", QColor(255, 120, 0), true},
    {"Undefined", QColor(160, 160, 160), true},
};

}  // namespace

LoopCandidatesDisplay::LoopCandidatesDisplay() {
  for (int s = 0; s < kNumLoopStatuses; ++s) {
    const QString name = kStatusStyles[s].name;
    show_properties_[s] = new rviz::BoolProperty(
        "Show " + name, kStatusStyles[s].shown, "Draw loops with status " + name.toLower() + ".",
        this, SLOT(redraw()));
    color_properties_[s] = new rviz::ColorProperty(
        name + " Color", kStatusStyles[s].color, "Colour of " + name.toLower() + " loops.", this,
        SLOT(redraw()));
  }
  line_width_property_ = new rviz::FloatProperty(
      "Line Width", 0.3f, "Width of the loop lines [m].", this, SLOT(redraw()));
  line_width_property_->setMin(0.001f);
  marker_size_property_ = new rviz::FloatProperty(
      "Undefined Marker Size", 1.5f,
      "Diameter of the sphere drawn at the origin of an undefined submap [m].", this,
      SLOT(redraw()));
  marker_size_property_->setMin(0.01f);
  show_text_property_ = new rviz::BoolProperty(
      "Show Text", true, "Label each loop with its submaps, vote proportion and overlap ratio.",
      this, SLOT(redraw()));
  text_height_property_ = new rviz::FloatProperty(
      "Text Height", 0.8f, "Character height of the labels [m].", this, SLOT(redraw()));
  text_height_property_->setMin(0.01f);
}

LoopCandidatesDisplay::~LoopCandidatesDisplay() {
  if (initialized()) clearVisuals();
}

void LoopCandidatesDisplay::onInitialize() {
  MFDClass::onInitialize();
  lines_ = std::make_unique<rviz::BillboardLine>(scene_manager_, scene_node_);
}

void LoopCandidatesDisplay::reset() {
  MFDClass::reset();
  last_msg_.reset();
  clearVisuals();
}

void LoopCandidatesDisplay::clearVisuals() {
  if (lines_) lines_->clear();
  markers_.clear();
  for (Label& label : labels_) {
    label.text.reset();  // detaches itself from the node
    scene_manager_->destroySceneNode(label.node);
  }
  labels_.clear();
}

void LoopCandidatesDisplay::processMessage(const LoopCandidateArray::ConstPtr& msg) {
  last_msg_ = msg;
  redraw();
}

void LoopCandidatesDisplay::redraw() {
  clearVisuals();
  if (!last_msg_ || !lines_) return;

  // The array is cumulative: place it with the newest transform rather than the stamp's.
  Ogre::Vector3 position;
  Ogre::Quaternion orientation;
  if (!context_->getFrameManager()->getTransform(last_msg_->header.frame_id, ros::Time(0),
                                                 position, orientation)) {
    setStatus(rviz::StatusProperty::Error, "Transform",
              "No transform from [" + QString::fromStdString(last_msg_->header.frame_id) +
                  "] to [" + fixed_frame_ + "]");
    return;
  }
  deleteStatus("Transform");
  scene_node_->setPosition(position);
  scene_node_->setOrientation(orientation);

  std::array<bool, kNumLoopStatuses> show{};
  for (int s = 0; s < kNumLoopStatuses; ++s) show[s] = show_properties_[s]->getBool();
  const LoopVisualList list = BuildLoopVisuals(*last_msg_, show);

  QString counts;
  for (int s = 0; s < kNumLoopStatuses; ++s) {
    counts += QString("%1 %2%3").arg(list.count_by_status[s]).arg(LoopStatusName(s))
                  .arg(s + 1 < kNumLoopStatuses ? ", " : "");
  }
  setStatus(rviz::StatusProperty::Ok, "Loops", counts);
  if (list.num_invalid > 0) {
    setStatus(rviz::StatusProperty::Warn, "Invalid",
              QString("%1 candidates without a finite origin or with an unknown status")
                  .arg(list.num_invalid));
  } else {
    deleteStatus("Invalid");
  }

  size_t num_segments = 0;
  for (const LoopVisual& v : list.visuals) num_segments += v.has_segment ? 1 : 0;
  lines_->setLineWidth(line_width_property_->getFloat());
  lines_->setMaxPointsPerLine(2);
  lines_->setNumLines(static_cast<uint32_t>(std::max<size_t>(num_segments, 1)));

  const float text_height = text_height_property_->getFloat();
  const float marker_size = marker_size_property_->getFloat();
  bool first_line = true;
  for (const LoopVisual& v : list.visuals) {
    Ogre::ColourValue color = color_properties_[v.status]->getOgreColor();
    const Ogre::Vector3 current = ToOgre(v.current_origin);
    Ogre::Vector3 label_position = current;
    if (v.has_segment) {
      const Ogre::Vector3 history = ToOgre(v.history_origin);
      if (!first_line) lines_->newLine();
      first_line = false;
      lines_->addPoint(current, color);
      lines_->addPoint(history, color);
      label_position = 0.5f * (current + history);
    } else {
      auto marker = std::make_unique<rviz::Shape>(rviz::Shape::Sphere, scene_manager_, scene_node_);
      marker->setPosition(current);
      marker->setScale(Ogre::Vector3(marker_size, marker_size, marker_size));
      marker->setColor(color);
      markers_.push_back(std::move(marker));
    }
    if (show_text_property_->getBool()) {
      Label label;
      label.node = scene_node_->createChildSceneNode();
      label.node->setPosition(label_position + Ogre::Vector3(0.f, 0.f, 0.5f * marker_size + text_height));
      label.text = std::make_unique<rviz::MovableText>(v.label, "Liberation Sans", text_height, color);
      label.text->setTextAlignment(rviz::MovableText::H_CENTER, rviz::MovableText::V_BELOW);
      label.node->attachObject(label.text.get());
      labels_.push_back(std::move(label));
    }
  }
  context_->queueRender();
}

}  // namespace rviz_plugins
}  // namespace multisession_mapper

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(multisession_mapper::rviz_plugins::LoopCandidatesDisplay, rviz::Display)
