#pragma once
/// @file
/// What the loader corrected or chose (io::VolumeInfo::notices: a gantry tilt resampled,
/// missing slices filled, duplicates dropped, which series of a folder, which time point of a
/// 4-D series), shown where the user looks: a dismissable banner above the view listing every
/// notice (reopened from Help > Load Notes), the most important one in the status bar, and the
/// console. For a 4-D series the banner also offers the other time points.

#include <filesystem>
#include <string>
#include <vector>

#include <QFrame>
#include <QString>
#include <QStringList>

#include "vh/io/volume_loader.h"
#include "vh/runtime/scene.h"
#include "vh/ui/panels/range_spin_box.h"

class QLabel;
class QPushButton;
class QScrollArea;
class QToolButton;
class QWidget;

namespace vh::ui {

/// How much a notice matters to someone touching the volume, 0 first: what moved voxels (a
/// gantry tilt, missing slices), what the values mean (a PET in SUV or not), uneven spacing,
/// then what was left out (duplicates, skipped series), then what was chosen (the time point,
/// the series). Unknown text ranks after these; the scene's note on its tool ("tool: ...") last.
int noticeRank(const std::string& notice);

/// The notice to show first (status bar): the lowest noticeRank(), the first of equals; empty
/// when there is none.
std::string primaryNotice(const std::vector<std::string>& notices);

/// The status bar's line for `notices`: how many there are and where to read them first (a long
/// line is cut at its end, so the pointer survives), then primaryNotice(); empty when none.
QString statusNote(const std::vector<std::string>& notices);

/// The banner above the view: one summary line (the count and the most important notice) with a
/// Details switch; the details are a list of bounded height (kMaxDetailLines, scrolled beyond),
/// so that a scan with many notes never squeezes the view. Hidden while there is nothing to say;
/// the close button hides it and reopen() (Help > Load Notes) shows it again, details open.
class LoadNoticePanel : public QFrame {
  Q_OBJECT

 public:
  /// Lines of the details list shown at most; more scroll.
  static constexpr int kMaxDetailLines = 6;

  explicit LoadNoticePanel(QWidget* parent = nullptr);

  /// Lists `info.notices` of the volume just shown, titled with `title` (the window's scene
  /// name); shown when there are notices, hidden otherwise. `spec` and `opened` are what was
  /// loaded: a 4-D series (info.phase_count > 1) offers its other time points, reloading
  /// `spec` with VolumeSpec::phase changed (reloadRequested()).
  void setLoaded(const QString& title, const runtime::SceneSpec& spec, const io::VolumeInfo& info,
                 const std::filesystem::path& opened);
  /// Shows the panel again (Help > Load Notes); says so when the volume needed no notes.
  void reopen();

  const QStringList& notices() const noexcept { return notices_; }
  /// Shows or hides the details list (the summary line stays).
  void setDetailsShown(bool shown);
  bool detailsShown() const;
  /// The time point chooser (1-based, as shown); hidden unless the volume is 4-D.
  RangeIntSpinBox* phaseSpinBox() const noexcept { return phase_spin_; }
  /// Reloads the chosen time point (emits reloadRequested()).
  QPushButton* phaseLoadButton() const noexcept { return phase_load_; }

 signals:
  /// The user asked for time point `spec.volume.phase` (0-based) of the 4-D series shown.
  void reloadRequested(const vh::runtime::SceneSpec& spec, const std::filesystem::path& opened);

 private:
  void refresh();

  QLabel* summary_;
  QToolButton* details_;
  QScrollArea* details_area_;
  QLabel* text_;
  QToolButton* close_;
  QWidget* phase_row_;
  QLabel* phase_label_;
  RangeIntSpinBox* phase_spin_;
  QPushButton* phase_load_;
  QString title_;
  QStringList notices_;
  runtime::SceneSpec spec_;
  std::filesystem::path opened_;
  int phase_count_ = 1;
};

}  // namespace vh::ui
