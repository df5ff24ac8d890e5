#pragma once
/// @file
/// What the application remembers between runs (QSettings): the view's look (ViewLook: colours,
/// rendering mode and preset, orientation marker, device tool), the last coupling gains, recent
/// files and the last folder, and the PACS server File > Open from PACS queries.
/// Window geometry and dock layout are stored by MainWindow beside these ("window/geometry",
/// "window/state").

#include <QString>
#include <QStringList>

#include "vh/io/pacs.h"
#include "vh/ui/view/view_look.h"

class QSettings;

namespace vh::ui {

struct Preferences : ViewLook {
  static constexpr int kMaxRecentFiles = 10;

  /// Coupling gains used for volumes opened without a scene file (a scene file's own gains win).
  double linear_stiffness_N_per_m = 1000.0;       ///< [N/m]
  double torsional_stiffness_Nm_per_rad = 1.0;    ///< [N*m/rad]
  bool passivity_control = false;                 ///< haptics::CouplingGains::passivity_control.
  /// The Segments panel's sound choices: the burr's sound, and the alert tone on touching a
  /// critical segment or a technique rule firing.
  bool burr_sound = false;
  bool alert_sound = false;

  QStringList recent_files;                       ///< Most recent first, at most kMaxRecentFiles.
  QString last_folder;                            ///< Where the last file dialog ended.
  /// The shared datasets' folder the user chose (File > Data Folder; empty: the installed or
  /// build-time one). runtime::setPreferredSharedDatasetsDir() takes it; VH_SHARED_DATASETS_DIR wins.
  QString datasets_dir;

  /// The DICOM server of File > Open from PACS: host, port, its AE title and ours (timeouts
  /// keep io::PacsServer's defaults and are not stored).
  io::PacsServer pacs;

  /// Puts `path` first in recent_files (removing an older entry of it), keeping kMaxRecentFiles.
  void addRecentFile(const QString& path);

  /// Reads the values under "preferences/" (missing or invalid entries keep their defaults).
  static Preferences load(QSettings& settings);
  /// Writes every value under "preferences/".
  void save(QSettings& settings) const;

  bool operator==(const Preferences& other) const = default;
};

/// Makes the application's settings file (QSettings' native file for the current organisation
/// and application names) owner-only: its folder 0700, the file 0600, created empty when missing.
/// It lists the recent scans' paths, often folders named after patients. Qt rewrites the file by
/// renaming a new one over it with the old one's permissions, so one call at start-up keeps it so.
/// Never throws: a folder or file that cannot be made private is left as it was.
void makeSettingsPrivate() noexcept;

}  // namespace vh::ui
