#include "vh/ui/panels/igtl_panel.h"

#include <algorithm>
#include <cmath>
#include <iostream>

#include <QAction>
#include <QCheckBox>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QLabel>
#include <QSpinBox>
#include <QStatusBar>
#include <QTimer>

namespace vh::ui {

IgtlSettings clampIgtlSettings(IgtlSettings s, double servo_rate_Hz) {
  s.port = std::clamp(s.port, 1, 65535);
  const double top = servo_rate_Hz > 1.0 && std::isfinite(servo_rate_Hz) ? servo_rate_Hz : 1000.0;
  if (!std::isfinite(s.rate_Hz)) s.rate_Hz = 60.0;
  s.rate_Hz = std::clamp(s.rate_Hz, 1.0, top);
  return s;
}

IgtlPanel::IgtlPanel(QStatusBar* status_bar, double servo_rate_Hz, QWidget* dialog_parent)
    : QObject(dialog_parent), servo_rate_Hz_(servo_rate_Hz), dialog_parent_(dialog_parent) {
  label_ = new QLabel(status_bar);
  label_->setObjectName("igtlStatus");
  label_->hide();
  if (status_bar != nullptr) status_bar->addPermanentWidget(label_);
  action_ = new QAction("&OpenIGTLink Server…", this);
  action_->setStatusTip("Stream the proxy and device poses, force and contacts to 3D Slicer; receive volumes from it");
  connect(action_, &QAction::triggered, this, [this] { openDialog(); });
  timer_ = new QTimer(this);
  timer_->setInterval(100);
  connect(timer_, &QTimer::timeout, this, [this] { poll(); });
}

IgtlPanel::~IgtlPanel() {
  if (link_ != nullptr) link_->stop();
}

bool IgtlPanel::apply(const IgtlSettings& requested, QString* error) {
  const IgtlSettings s = clampIgtlSettings(requested, servo_rate_Hz_);
  if (link_ != nullptr) {
    link_->stop();
    link_.reset();
  }
  settings_ = s;
  bool ok = true;
  if (s.enabled) {
    igtl::LinkOptions options;
    options.port = s.port;
    options.rate_Hz = s.rate_Hz;
    options.servo_rate_Hz = servo_rate_Hz_;
    if (names_ != nullptr) {
      options.segment_name = [names = names_](const runtime::HapticSnapshot& snapshot) {
        return names->name(snapshot.contacts > 0 ? snapshot.segment : -1);
      };
    }
    try {
      auto link = std::make_unique<igtl::IgtlLink>(channel_, options);
      link->start();
      link_ = std::move(link);
    } catch (const std::exception& e) {
      settings_.enabled = false;
      ok = false;
      if (error != nullptr) *error = QString::fromStdString(e.what());
      std::cerr << "volume-haptics: " << e.what() << '\n';
    }
  }
  if (link_ != nullptr) timer_->start();
  else timer_->stop();
  poll();
  return ok;
}

QString IgtlPanel::statusText() const {
  return link_ != nullptr ? QString::fromStdString(link_->statusText()) : QString("OpenIGTLink off");
}

void IgtlPanel::poll() {
  label_->setText(statusText());
  label_->setVisible(link_ != nullptr);
  if (link_ == nullptr) return;
  for (const std::string& n : link_->takeNotices()) {
    std::cerr << "volume-haptics: " << n << '\n';
    emit message(QString::fromStdString(n), 5000);
  }
  while (std::optional<io::LoadedVolume> v = link_->takeReceivedVolume()) {
    if (on_volume_) on_volume_(std::move(*v));
  }
}

void IgtlPanel::openDialog() {
  QDialog dialog(dialog_parent_);
  dialog.setWindowTitle("OpenIGTLink Server");
  auto* form = new QFormLayout(&dialog);
  auto* enabled = new QCheckBox("Listen for a client (e.g. 3D Slicer's OpenIGTLinkIF)", &dialog);
  enabled->setChecked(settings_.enabled || link_ == nullptr);
  auto* port = new QSpinBox(&dialog);
  port->setObjectName("igtlPort");
  port->setRange(1, 65535);
  port->setValue(settings_.port);
  auto* rate = new QDoubleSpinBox(&dialog);
  rate->setObjectName("igtlRate");
  rate->setRange(1.0, std::max(1.0, servo_rate_Hz_));
  rate->setDecimals(0);
  rate->setSuffix(" Hz");
  rate->setValue(settings_.rate_Hz);
  form->addRow(enabled);
  form->addRow("Port", port);
  form->addRow("Rate", rate);
  form->addRow(new QLabel("Sends ProxyToRAS, DeviceToRAS (TRANSFORM), Force (SENSOR) and ContactState (STRING);\n"
                          "an IMAGE sent from Slicer opens as the new scene.",
                          &dialog));
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel, &dialog);
  form->addRow(buttons);
  connect(buttons, &QDialogButtonBox::accepted, &dialog, &QDialog::accept);
  connect(buttons, &QDialogButtonBox::rejected, &dialog, &QDialog::reject);
  if (dialog.exec() != QDialog::Accepted) return;
  QString error;
  if (!apply({enabled->isChecked(), port->value(), rate->value()}, &error)) emit message(error, 8000);
}

bool IgtlPanel::applySceneSection(const std::optional<runtime::OpenIgtlinkSpec>& section, QString* error) {
  if (!section.has_value()) return true;
  if (running() && settings_.port == section->port && settings_.rate_Hz == section->rate_Hz) return true;
  return apply({true, section->port, section->rate_Hz}, error);
}

}  // namespace vh::ui
