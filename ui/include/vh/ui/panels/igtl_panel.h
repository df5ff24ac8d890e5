#pragma once
/// @file
/// The GUI's OpenIGTLink switch: owns the snapshot channel the session's haptic
/// threads feed (set once, at start-up, so switching the link on never rebuilds them) and the
/// link (vh::igtl::IgtlLink), off by default; a menu action opens a small dialog (on/off, port,
/// rate, the address to listen on, the clients allowed); a permanent status-bar label says
/// "OpenIGTLink: listening on 127.0.0.1:18944" / "connected to 127.0.0.1:53412 (...)" and the
/// connections refused; a 100 ms timer shows the link's notices and, for a volume received from
/// the client (an IMAGE message), asks the user (sender, size, spacing, and that a recording in
/// progress will be ended) before handing it to the main window, which opens it as a new scene.
/// A volume declined is dropped; nothing received is ever opened without a yes.

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <QObject>
#include <QString>

#include "vh/igtl/igtl_link.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/snapshot_channel.h"

class QAction;
class QLabel;
class QStatusBar;
class QTimer;
class QWidget;

namespace vh::ui {

/// The dialog's choice: the link on or off, its port and rate, who may connect.
struct IgtlSettings {
  bool enabled = false;
  int port = igtl::kDefaultPort;  ///< 1..65535
  double rate_Hz = 60.0;          ///< Frames per second [Hz], 1..servo rate.
  std::string bind_address = "127.0.0.1";    ///< igtl::LinkOptions::bind_address
  std::vector<std::string> allowed_clients;  ///< igtl::LinkOptions::allowed_clients
};

/// What the user is asked about a received volume.
struct IgtlVolumeOffer {
  std::string peer;                ///< Sender "address:port".
  std::string name;                ///< The IMAGE's device name (escaped).
  std::array<int, 3> dims{};       ///< Voxels along i, j, k.
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Zero();  ///< [mm]
  bool recording = false;          ///< A recording runs: opening ends it first.
};

/// The question's text ("Open the volume 'CT' sent by 10.1.2.3:5000 over OpenIGTLink? ...").
QString igtlOfferText(const IgtlVolumeOffer& offer);

/// Clamps a requested setting to what the link accepts: port into 1..65535, rate into
/// [1, servo_rate_Hz] (a non-finite rate becomes the 60 Hz default).
IgtlSettings clampIgtlSettings(IgtlSettings settings, double servo_rate_Hz);

class IgtlPanel : public QObject {
  Q_OBJECT

 public:
  /// @param status_bar gets a permanent label (hidden while the link is off).
  /// @param servo_rate_Hz the session's servo rate (the rate's upper bound) [Hz].
  IgtlPanel(QStatusBar* status_bar, double servo_rate_Hz, QWidget* dialog_parent);
  ~IgtlPanel() override;  ///< Stops the link.

  /// The channel to give the session (Session::setMonitor()) before the first scene.
  const std::shared_ptr<runtime::SnapshotChannel>& channel() const noexcept { return channel_; }
  /// The names the link sends as "segment" in ContactState (the scene's segments), kept up to
  /// date by the window (SegmentsController::names()); applies from the next apply().
  void setSegmentNames(std::shared_ptr<const runtime::SegmentNameTable> names) { names_ = std::move(names); }
  /// "OpenIGTLink Server…": opens the dialog and applies its choice.
  QAction* action() const noexcept { return action_; }

  /// Starts (or restarts) the link with `settings` (clamped), or stops it when not enabled.
  /// @return false with `error` set ("OpenIGTLink: cannot listen on port N (in use?)") when
  ///         the port cannot be bound; the link is then off.
  bool apply(const IgtlSettings& settings, QString* error = nullptr);
  IgtlSettings settings() const noexcept { return settings_; }
  /// A scene file's "openigtlink" section: switches the link on, or moves it to the section's
  /// port and rate when it runs elsewhere; nothing without a section.
  /// @return false with `error` set, as apply(), when the port cannot be bound.
  bool applySceneSection(const std::optional<runtime::OpenIgtlinkSpec>& section, QString* error = nullptr);
 private:
  std::shared_ptr<const runtime::SegmentNameTable> names_;

 public:
  bool running() const noexcept { return link_ != nullptr && link_->running(); }
  /// The status-bar text ("OpenIGTLink: listening on 127.0.0.1:18944", "OpenIGTLink off").
  QString statusText() const;
  igtl::IgtlLink* link() const noexcept { return link_.get(); }

  /// Called on the GUI thread with each volume a client sent and the user accepted.
  void setOnVolume(std::function<void(io::LoadedVolume)> on_volume) { on_volume_ = std::move(on_volume); }
  /// Whether a recording runs (asked before each offer; the window's recorder).
  void setRecordingQuery(std::function<bool()> recording) { recording_ = std::move(recording); }
  /// Asks the user about a received volume; true opens it. Default: a Yes/No message box
  /// (No is the default button). Tests replace it.
  void setConfirmVolume(std::function<bool(const IgtlVolumeOffer&)> confirm) { confirm_ = std::move(confirm); }
  /// One timer step (tests call it directly): status label, notices, received volumes.
  void poll();

 signals:
  /// A notice for the status bar (a client connected, a message rejected, an error).
  void message(const QString& text, int timeout_ms);

 private:
  void openDialog();

  std::shared_ptr<runtime::SnapshotChannel> channel_ = std::make_shared<runtime::SnapshotChannel>();
  std::unique_ptr<igtl::IgtlLink> link_;
  IgtlSettings settings_;
  double servo_rate_Hz_;
  QWidget* dialog_parent_;
  QLabel* label_ = nullptr;
  QAction* action_ = nullptr;
  QTimer* timer_ = nullptr;
  std::function<void(io::LoadedVolume)> on_volume_;
  std::function<bool()> recording_;
  std::function<bool(const IgtlVolumeOffer&)> confirm_;
  bool asking_ = false;  ///< An offer is on screen (poll() runs again inside the dialog's loop).
};

}  // namespace vh::ui
