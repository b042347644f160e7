#include "map_session_panel.h"

#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPlainTextEdit>
#include <QPushButton>
#include <QTimer>
#include <QVBoxLayout>
#include <QtConcurrent/QtConcurrentRun>

#include <multisession_mapper/FinishSession.h>
#include <multisession_mapper/LoopCandidate.h>
#include <multisession_mapper/SaveMap.h>
#include <rviz/config.h>

namespace multisession_mapper {
namespace rviz_plugins {
namespace {

// How long a worker waits for a service to appear before reporting it missing [s].
constexpr double kServiceWaitS = 2.0;

// Defaults match the topic and service names of the nodelets (launch/mapping.launch).
const char* const kDefaultSubmapsTopic = "submaps";
const char* const kDefaultLoopsTopic = "loop_candidates";
const char* const kDefaultSummaryTopic = "change_summary";
const char* const kDefaultFinishService = "finish_session";
const char* const kDefaultSaveService = "save_map";
const char* const kDefaultMapDirParam = "map_merging/map_dir";

template <typename Srv>
ServiceCallResult CallService(const std::string& name, Srv srv) {
  ServiceCallResult result;
  if (!ros::service::waitForService(name, ros::Duration(kServiceWaitS))) {
    result.text = QString("service %1 is not advertised").arg(QString::fromStdString(name));
    return result;
  }
  if (!ros::service::call(name, srv)) {
    result.text = QString("call to %1 failed").arg(QString::fromStdString(name));
    return result;
  }
  result.success = srv.response.success;
  result.text = QString::fromStdString(srv.response.message);
  return result;
}

QLineEdit* AddNameEdit(QFormLayout* form, const QString& label, const QString& value) {
  auto* edit = new QLineEdit(value);
  form->addRow(label, edit);
  return edit;
}

}  // namespace

MapSessionPanel::MapSessionPanel(QWidget* parent) : rviz::Panel(parent) {
  auto* layout = new QVBoxLayout(this);

  auto* status_box = new QGroupBox("Map");
  auto* status_form = new QFormLayout(status_box);
  map_dir_label_ = new QLabel("(unknown)");
  map_dir_label_->setWordWrap(true);
  map_dir_label_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  sessions_label_ = new QLabel("no submap received");
  sessions_label_->setWordWrap(true);
  loops_label_ = new QLabel("no loop candidates received");
  loops_label_->setWordWrap(true);
  status_form->addRow("Directory:", map_dir_label_);
  status_form->addRow("Sessions:", sessions_label_);
  status_form->addRow("Loops:", loops_label_);
  layout->addWidget(status_box);

  summary_text_ = new QPlainTextEdit;
  summary_text_->setReadOnly(true);
  summary_text_->setPlaceholderText("change summary of the last merge");
  summary_text_->setMaximumHeight(90);
  layout->addWidget(summary_text_);

  auto* buttons = new QHBoxLayout;
  finish_button_ = new QPushButton("Finish session");
  finish_button_->setToolTip("Merge the current session into the map and save it");
  save_button_ = new QPushButton("Save map");
  buttons->addWidget(finish_button_);
  buttons->addWidget(save_button_);
  layout->addLayout(buttons);
  result_label_ = new QLabel;
  result_label_->setWordWrap(true);
  layout->addWidget(result_label_);

  auto* names_box = new QGroupBox("Names");
  auto* names_form = new QFormLayout(names_box);
  submaps_topic_edit_ = AddNameEdit(names_form, "Submaps topic", kDefaultSubmapsTopic);
  loops_topic_edit_ = AddNameEdit(names_form, "Loops topic", kDefaultLoopsTopic);
  summary_topic_edit_ = AddNameEdit(names_form, "Summary topic", kDefaultSummaryTopic);
  finish_service_edit_ = AddNameEdit(names_form, "Finish service", kDefaultFinishService);
  save_service_edit_ = AddNameEdit(names_form, "Save service", kDefaultSaveService);
  map_dir_param_edit_ = AddNameEdit(names_form, "Map dir parameter", kDefaultMapDirParam);
  save_dir_edit_ = AddNameEdit(names_form, "Save to", "");
  save_dir_edit_->setPlaceholderText("(the configured map directory)");
  layout->addWidget(names_box);
  layout->addStretch(1);

  call_watcher_ = new QFutureWatcher<ServiceCallResult>(this);
  map_dir_timer_ = new QTimer(this);

  connect(submaps_topic_edit_, SIGNAL(editingFinished()), this, SLOT(subscribe()));
  connect(loops_topic_edit_, SIGNAL(editingFinished()), this, SLOT(subscribe()));
  connect(summary_topic_edit_, SIGNAL(editingFinished()), this, SLOT(subscribe()));
  connect(map_dir_param_edit_, SIGNAL(editingFinished()), this, SLOT(refreshMapDir()));
  for (QLineEdit* edit : {submaps_topic_edit_, loops_topic_edit_, summary_topic_edit_,
                          finish_service_edit_, save_service_edit_, map_dir_param_edit_}) {
    connect(edit, SIGNAL(editingFinished()), this, SIGNAL(configChanged()));
  }
  connect(finish_button_, SIGNAL(clicked()), this, SLOT(finishSession()));
  connect(save_button_, SIGNAL(clicked()), this, SLOT(saveMap()));
  connect(call_watcher_, SIGNAL(finished()), this, SLOT(serviceCallDone()));
  connect(map_dir_timer_, SIGNAL(timeout()), this, SLOT(refreshMapDir()));
}

MapSessionPanel::~MapSessionPanel() {
  // A call still running finishes on its worker thread; its result is dropped with the watcher.
  call_watcher_->disconnect(this);
}

void MapSessionPanel::onInitialize() {
  subscribe();
  refreshMapDir();
  map_dir_timer_->start(1000);
}

void MapSessionPanel::subscribe() {
  const auto topic = [](QLineEdit* edit) { return edit->text().trimmed().toStdString(); };
  submaps_sub_.shutdown();
  loops_sub_.shutdown();
  summary_sub_.shutdown();
  try {
    if (!topic(submaps_topic_edit_).empty()) {
      // A stored map is replayed as a burst of one message per submap: keep them all.
      submaps_sub_ =
          nh_.subscribe(topic(submaps_topic_edit_), 10000, &MapSessionPanel::onSubmap, this);
    }
    if (!topic(loops_topic_edit_).empty()) {
      loops_sub_ = nh_.subscribe(topic(loops_topic_edit_), 1, &MapSessionPanel::onLoops, this);
    }
    if (!topic(summary_topic_edit_).empty()) {
      summary_sub_ = nh_.subscribe(topic(summary_topic_edit_), 1, &MapSessionPanel::onSummary, this);
    }
  } catch (const ros::Exception& e) {
    result_label_->setText(QString("cannot subscribe: ") + e.what());
  }
  sessions_.clear();
  updateSessionsLabel();
}

// ROS callbacks may run outside the GUI thread: widgets are only touched in queued lambdas.
void MapSessionPanel::onSubmap(const SubmapInfo::ConstPtr& msg) {
  QMetaObject::invokeMethod(this, [this, msg]() {
    sessions_[msg->session].points_by_submap[msg->id] = msg->num_points;
    updateSessionsLabel();
  }, Qt::QueuedConnection);
}

void MapSessionPanel::onLoops(const LoopCandidateArray::ConstPtr& msg) {
  QMetaObject::invokeMethod(this, [this, msg]() {
    int counts[4] = {0, 0, 0, 0};
    for (const LoopCandidate& c : msg->candidates) {
      if (c.status < 4) ++counts[c.status];
    }
    loops_label_->setText(QString("%1 accepted, %2 rejected, %3 candidate, %4 undefined")
                              .arg(counts[LoopCandidate::ACCEPTED])
                              .arg(counts[LoopCandidate::REJECTED])
                              .arg(counts[LoopCandidate::CANDIDATE])
                              .arg(counts[LoopCandidate::UNDEFINED]));
  }, Qt::QueuedConnection);
}

void MapSessionPanel::onSummary(const std_msgs::String::ConstPtr& msg) {
  QMetaObject::invokeMethod(this, [this, msg]() {
    summary_text_->setPlainText(QString::fromStdString(msg->data));
  }, Qt::QueuedConnection);
}

void MapSessionPanel::updateSessionsLabel() {
  if (sessions_.empty()) {
    sessions_label_->setText("no submap received");
    return;
  }
  QStringList parts;
  size_t total_submaps = 0;
  uint64_t total_points = 0;
  for (const auto& [name, stats] : sessions_) {
    total_submaps += stats.points_by_submap.size();
    for (const auto& [id, points] : stats.points_by_submap) total_points += points;
    parts << QString("%1: %2 submaps").arg(QString::fromStdString(name))
                 .arg(stats.points_by_submap.size());
  }
  sessions_label_->setText(QString("%1 sessions, %2 submaps, %3 points\n%4")
                               .arg(sessions_.size()).arg(total_submaps).arg(total_points)
                               .arg(parts.join("; ")));
}

void MapSessionPanel::refreshMapDir() {
  const std::string param = map_dir_param_edit_->text().trimmed().toStdString();
  std::string dir;
  if (!param.empty() && ros::param::getCached(param, dir) && !dir.empty()) {
    map_dir_label_->setText(QString::fromStdString(dir));
  } else {
    map_dir_label_->setText(QString("(parameter %1 not set)").arg(QString::fromStdString(param)));
  }
}

void MapSessionPanel::startCall(const QString& what, std::function<ServiceCallResult()> call) {
  if (call_watcher_->isRunning()) return;
  finish_button_->setEnabled(false);
  save_button_->setEnabled(false);
  call_name_ = what;
  result_label_->setText(what + ": running...");
  call_watcher_->setFuture(QtConcurrent::run(std::move(call)));
}

void MapSessionPanel::finishSession() {
  const std::string service = finish_service_edit_->text().trimmed().toStdString();
  startCall("Finish session", [service]() {
    return CallService(service, multisession_mapper::FinishSession());
  });
}

void MapSessionPanel::saveMap() {
  const std::string service = save_service_edit_->text().trimmed().toStdString();
  multisession_mapper::SaveMap srv;
  srv.request.map_dir = save_dir_edit_->text().trimmed().toStdString();
  startCall("Save map", [service, srv]() { return CallService(service, srv); });
}

void MapSessionPanel::serviceCallDone() {
  const ServiceCallResult result = call_watcher_->result();
  result_label_->setText(QString("%1 %2: %3")
                             .arg(call_name_)
                             .arg(result.success ? "succeeded" : "failed")
                             .arg(result.text));
  result_label_->setStyleSheet(result.success ? "" : "color: #c00000;");
  finish_button_->setEnabled(true);
  save_button_->setEnabled(true);
  refreshMapDir();
}

void MapSessionPanel::load(const rviz::Config& config) {
  rviz::Panel::load(config);
  const std::pair<const char*, QLineEdit*> keys[] = {
      {"Submaps Topic", submaps_topic_edit_}, {"Loops Topic", loops_topic_edit_},
      {"Summary Topic", summary_topic_edit_}, {"Finish Service", finish_service_edit_},
      {"Save Service", save_service_edit_},   {"Map Dir Parameter", map_dir_param_edit_}};
  for (const auto& [key, edit] : keys) {
    QString value;
    if (config.mapGetString(key, &value)) edit->setText(value);
  }
  subscribe();
  refreshMapDir();
}

void MapSessionPanel::save(rviz::Config config) const {
  rviz::Panel::save(config);
  config.mapSetValue("Submaps Topic", submaps_topic_edit_->text());
  config.mapSetValue("Loops Topic", loops_topic_edit_->text());
  config.mapSetValue("Summary Topic", summary_topic_edit_->text());
  config.mapSetValue("Finish Service", finish_service_edit_->text());
  config.mapSetValue("Save Service", save_service_edit_->text());
  config.mapSetValue("Map Dir Parameter", map_dir_param_edit_->text());
}

}  // namespace rviz_plugins
}  // namespace multisession_mapper

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(multisession_mapper::rviz_plugins::MapSessionPanel, rviz::Panel)
