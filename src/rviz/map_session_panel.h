// RViz panel for a mapping session: the map directory, the sessions and their submap counts
// (from SubmapInfo), the loop counts of the current session by status (from LoopCandidateArray),
// the last change summary, and buttons that call the finish_session and save_map services.
// Service calls run on a worker thread (QtConcurrent) so the GUI never blocks while the map is
// merged and saved; the result message is shown when the call returns.
// Topic, service and parameter names are editable and saved in the .rviz file.
#pragma once

#ifndef Q_MOC_RUN
#include <functional>
#include <map>
#include <string>

#include <multisession_mapper/LoopCandidateArray.h>
#include <multisession_mapper/SubmapInfo.h>
#include <ros/ros.h>
#include <rviz/panel.h>
#include <std_msgs/String.h>
#endif

#include <QFutureWatcher>
#include <QString>

class QLabel;
class QLineEdit;
class QPlainTextEdit;
class QPushButton;
class QTimer;

namespace multisession_mapper {
namespace rviz_plugins {

// Outcome of one service call, produced on the worker thread.
struct ServiceCallResult {
  bool success = false;
  QString text;
};

class MapSessionPanel : public rviz::Panel {
  Q_OBJECT

 public:
  explicit MapSessionPanel(QWidget* parent = nullptr);
  ~MapSessionPanel() override;

  void onInitialize() override;
  void load(const rviz::Config& config) override;
  void save(rviz::Config config) const override;

 private Q_SLOTS:
  void subscribe();          // (re)subscribes after a topic name was edited
  void refreshMapDir();      // polls the map directory parameter
  void finishSession();
  void saveMap();
  void serviceCallDone();

 private:
  struct SessionStats {
    std::map<uint32_t, uint32_t> points_by_submap;  // latest SubmapInfo per submap id
  };

  void onSubmap(const SubmapInfo::ConstPtr& msg);
  void onLoops(const LoopCandidateArray::ConstPtr& msg);
  void onSummary(const std_msgs::String::ConstPtr& msg);
  void updateSessionsLabel();
  void startCall(const QString& what, std::function<ServiceCallResult()> call);

  ros::NodeHandle nh_;
  ros::Subscriber submaps_sub_, loops_sub_, summary_sub_;
  std::map<std::string, SessionStats> sessions_;

  QLineEdit* submaps_topic_edit_;
  QLineEdit* loops_topic_edit_;
  QLineEdit* summary_topic_edit_;
  QLineEdit* finish_service_edit_;
  QLineEdit* save_service_edit_;
  QLineEdit* map_dir_param_edit_;
  QLineEdit* save_dir_edit_;
  QLabel* map_dir_label_;
  QLabel* sessions_label_;
  QLabel* loops_label_;
  QPlainTextEdit* summary_text_;
  QPushButton* finish_button_;
  QPushButton* save_button_;
  QLabel* result_label_;
  QTimer* map_dir_timer_;
  QFutureWatcher<ServiceCallResult>* call_watcher_;
  QString call_name_;
};

}  // namespace rviz_plugins
}  // namespace multisession_mapper
