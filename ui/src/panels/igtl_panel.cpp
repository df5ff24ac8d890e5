#include "vh/ui/panels/igtl_panel.h"

#include <algorithm>
#include <cmath>
#include <iostream>

#include <QAction>
#include <QCheckBox>
#include <QDialog>
#include <QDialogButtonBox>
#include <QFormLayout>
#include <QLabel>
#include <QLineEdit>
#include <QMessageBox>
#include <QStatusBar>
#include <QRegularExpression>
#include <QTimer>

#include "vh/ui/panels/range_spin_box.h"

namespace vh::ui {

IgtlSettings clampIgtlSettings(IgtlSettings s, double servo_rate_Hz) {
  s.port = std::clamp(s.port, 1, 65535);
  const double top = servo_rate_Hz > 1.0 && std::isfinite(servo_rate_Hz) ? servo_rate_Hz : 1000.0;
  if (!std::isfinite(s.rate_Hz)) s.rate_Hz = 60.0;
  s.rate_Hz = std::clamp(s.rate_Hz, 1.0, top);
  return s;
}

QString igtlOfferText(const IgtlVolumeOffer& o) {
  QString text = QString("Open the volume '%1' sent by %2 over OpenIGTLink?\n\n%3 x %4 x %5 voxels, spacing %6 x %7 x %8 mm.\n"
                         "It replaces the current scene.")
                     .arg(QString::fromStdString(o.name), QString::fromStdString(o.peer))
                     .arg(o.dims[0])
                     .arg(o.dims[1])
                     .arg(o.dims[2])
                     .arg(o.spacing_mm.x(), 0, 'g', 4)
                     .arg(o.spacing_mm.y(), 0, 'g', 4)
                     .arg(o.spacing_mm.z(), 0, 'g', 4);
  if (o.recording) text += "\nThe recording in progress will be ended and saved first.";
  return text;
}

namespace {

/// "a, b" from a list, and back (blanks and empty items dropped).
QString joinAddresses(const std::vector<std::string>& list) {
  QStringList out;
  for (const std::string& a : list) out << QString::fromStdString(a);
  return out.join(", ");
}
std::vector<std::string> splitAddresses(const QString& text) {
  std::vector<std::string> out;
  for (const QString& a : text.split(QRegularExpression("[,;\\s]+"), Qt::SkipEmptyParts)) out.push_back(a.toStdString());
  return out;
}

}  // namespace

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
    options.bind_address = s.bind_address;
    options.allowed_clients = s.allowed_clients;
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
  if (asking_) return;  // the question on screen runs this timer's loop: one offer at a time
  std::optional<igtl::ReceivedImage> received = link_->takeReceivedImage();
  if (!received || received->volume.field == nullptr) return;
  IgtlVolumeOffer offer;
  offer.peer = received->peer;
  offer.name = igtl::escapeControl(received->volume.info.description);
  offer.dims = received->volume.field->geometry().dims;
  offer.spacing_mm = 1e3 * received->volume.field->geometry().spacing_m;
  offer.recording = recording_ && recording_();
  asking_ = true;
  bool yes = false;
  if (confirm_) {
    yes = confirm_(offer);
  } else {
    yes = QMessageBox::question(dialog_parent_, "Volume received over OpenIGTLink", igtlOfferText(offer),
                                QMessageBox::Yes | QMessageBox::No, QMessageBox::No) == QMessageBox::Yes;
  }
  asking_ = false;
  const std::string what = "OpenIGTLink: volume '" + offer.name + "' from " + offer.peer;
  std::cerr << "volume-haptics: " << what << (yes ? " opened" : " declined") << '\n';
  if (!yes) {
    emit message(QString::fromStdString(what + " declined"), 5000);
    return;
  }
  if (on_volume_) on_volume_(std::move(received->volume));
}

void IgtlPanel::openDialog() {
  QDialog dialog(dialog_parent_);
  dialog.setWindowTitle("OpenIGTLink Server");
  auto* form = new QFormLayout(&dialog);
  auto* enabled = new QCheckBox("Listen for a client (e.g. 3D Slicer's OpenIGTLinkIF)", &dialog);
  enabled->setChecked(settings_.enabled || link_ == nullptr);
  auto* port = new RangeIntSpinBox("the port", &dialog);
  port->setObjectName("igtlPort");
  port->setRange(1, 65535);
  port->setValue(settings_.port);
  auto* rate = new RangeSpinBox("the rate", &dialog);
  rate->setObjectName("igtlRate");
  rate->setRange(1.0, std::max(1.0, servo_rate_Hz_));
  rate->setDecimals(0);
  rate->setSuffix(" Hz");
  rate->setValue(settings_.rate_Hz);
  form->addRow(enabled);
  form->addRow("Port", port);
  form->addRow("Rate", rate);
  auto* bind = new QLineEdit(QString::fromStdString(settings_.bind_address), &dialog);
  bind->setObjectName("igtlBind");
  bind->setToolTip("127.0.0.1: only programs on this machine can connect. 0.0.0.0: every interface (then name the "
                   "clients allowed).");
  auto* allow = new QLineEdit(joinAddresses(settings_.allowed_clients), &dialog);
  allow->setObjectName("igtlAllow");
  allow->setPlaceholderText("e.g. 192.168.1.20, 192.168.1.21");
  allow->setToolTip("IPv4 addresses of the clients accepted besides this machine (127.0.0.1); others are refused and "
                    "shown in the status bar.");
  form->addRow("Listen on", bind);
  form->addRow("Allowed clients", allow);
  form->addRow(new QLabel("Sends ProxyToRAS, DeviceToRAS (TRANSFORM), Force (SENSOR) and ContactState (STRING);\n"
                          "an IMAGE sent from Slicer opens as the new scene after you say yes.",
                          &dialog));
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel, &dialog);
  form->addRow(buttons);
  connect(buttons, &QDialogButtonBox::accepted, &dialog, unlessRefused(dialog, {port, rate}, [&dialog] { dialog.accept(); }));
  connect(buttons, &QDialogButtonBox::rejected, &dialog, &QDialog::reject);
  if (dialog.exec() != QDialog::Accepted) return;
  QString error;
  if (!apply({enabled->isChecked(), port->value(), rate->value(), bind->text().trimmed().toStdString(),
              splitAddresses(allow->text())},
             &error)) {
    emit message(error, 8000);
  }
}

bool IgtlPanel::applySceneSection(const std::optional<runtime::OpenIgtlinkSpec>& section, QString* error) {
  if (!section.has_value()) return true;
  if (running() && settings_.port == section->port && settings_.rate_Hz == section->rate_Hz) return true;
  // The address and the clients allowed stay the user's (a scene file cannot open the link to
  // other machines).
  IgtlSettings s = settings_;
  s.enabled = true;
  s.port = section->port;
  s.rate_Hz = section->rate_Hz;
  return apply(s, error);
}

}  // namespace vh::ui
