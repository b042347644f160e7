// RViz display of multisession_mapper/LoopCandidateArray: a line between the origins of the two
// submaps of every loop, coloured by its status (candidate, accepted, rejected), a sphere at the
// current submap's origin for UNDEFINED submaps (no history submap won the vote), and the vote
// proportion p_j and overlap ratio as text (Ding et al., Sec. III-B and III-C).
// Structure after cartographer_rviz's SubmapsDisplay: a MessageFilterDisplay that keeps the last
// message (the array is latched and cumulative) and redraws it when a property changes.
#pragma once

#ifndef Q_MOC_RUN
#include <array>
#include <memory>
#include <vector>

#include <multisession_mapper/LoopCandidateArray.h>
#include <rviz/message_filter_display.h>
#endif

namespace Ogre {
class SceneNode;
}
namespace rviz {
class BillboardLine;
class BoolProperty;
class ColorProperty;
class FloatProperty;
class MovableText;
class Shape;
}  // namespace rviz

namespace multisession_mapper {
namespace rviz_plugins {

class LoopCandidatesDisplay
    : public rviz::MessageFilterDisplay<multisession_mapper::LoopCandidateArray> {
  Q_OBJECT

 public:
  LoopCandidatesDisplay();
  ~LoopCandidatesDisplay() override;

  void reset() override;

 protected:
  void onInitialize() override;

 private Q_SLOTS:
  // Redraws the last message with the current property values.
  void redraw();

 private:
  struct Label {
    Ogre::SceneNode* node = nullptr;
    std::unique_ptr<rviz::MovableText> text;
  };

  void processMessage(const LoopCandidateArray::ConstPtr& msg) override;
  void clearVisuals();

  std::array<rviz::ColorProperty*, 4> color_properties_{};  // index = LoopCandidate::status
  std::array<rviz::BoolProperty*, 4> show_properties_{};
  rviz::FloatProperty* line_width_property_ = nullptr;   // [m]
  rviz::FloatProperty* marker_size_property_ = nullptr;  // [m]
  rviz::BoolProperty* show_text_property_ = nullptr;
  rviz::FloatProperty* text_height_property_ = nullptr;  // [m]

  LoopCandidateArray::ConstPtr last_msg_;
  std::unique_ptr<rviz::BillboardLine> lines_;
  std::vector<std::unique_ptr<rviz::Shape>> markers_;
  std::vector<Label> labels_;
};

}  // namespace rviz_plugins
}  // namespace multisession_mapper
