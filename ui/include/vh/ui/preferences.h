#pragma once
/// @file
/// What the application remembers between runs (QSettings): colours, the last coupling gains,
/// the rendering mode and preset, the orientation marker, recent files and the last folder.
/// Window geometry and dock layout are stored by MainWindow beside these ("window/geometry",
/// "window/state").

#include <QColor>
#include <QString>
#include <QStringList>

#include "vh/ui/view/render_presets.h"

class QSettings;

namespace vh::ui {

struct Preferences {
  static constexpr int kMaxRecentFiles = 10;

  QColor background_bottom = QColor(15, 18, 23);  ///< View background, lower edge of the gradient.
  QColor background_top = QColor(56, 64, 79);     ///< View background, upper edge.
  QColor surface = QColor(237, 222, 189);         ///< Isosurface colour (bone).
  QColor tool = QColor(158, 166, 179);            ///< Proxy (solid) tool colour.
  QColor device = QColor(77, 191, 255);           ///< Device (wireframe) tool colour.

  /// Coupling gains used for volumes opened without a scene file (a scene file's own gains win).
  double linear_stiffness_N_per_m = 1000.0;       ///< [N/m]
  double torsional_stiffness_Nm_per_rad = 1.0;    ///< [N*m/rad]
  bool passivity_control = false;                 ///< haptics::CouplingGains::passivity_control.

  RenderMode mode = RenderMode::kIsosurface;
  VolumePreset preset = VolumePreset::kBone;
  bool orientation_marker = true;
  bool show_device = true;                        ///< Draw the device's (wireframe) tool.

  QStringList recent_files;                       ///< Most recent first, at most kMaxRecentFiles.
  QString last_folder;                            ///< Where the last file dialog ended.

  /// Puts `path` first in recent_files (removing an older entry of it), keeping kMaxRecentFiles.
  void addRecentFile(const QString& path);

  /// Reads the values under "preferences/" (missing or invalid entries keep their defaults).
  static Preferences load(QSettings& settings);
  /// Writes every value under "preferences/".
  void save(QSettings& settings) const;

  bool operator==(const Preferences& other) const = default;
};

}  // namespace vh::ui
