#pragma once
/// @file
/// Drilling in the GUI: Haptics > Drill (Ctrl+B) spins the burr up or down (Session::
/// setDrilling()); while the haptic threads drill, the voxels they remove reach the picture
/// within a frame (the removal log, drained every 20 ms into SceneActors::removeVoxels(), which
/// uploads only the touched box to the GPU); haptic threads rebuilt with the cavity (a tool,
/// segments or device change: Session keeps it) show it at their first drain, so the picture
/// and the hand keep the same cavity; removing voxels of a critical segment is an alert
/// and a "critical_removed" event in the recording ({"segment", "voxels", "mm3"}); File > Export
/// Drilled Volume writes the drilled scan (NRRD) and the removed region as a segment (.seg.nrrd)
/// for 3D Slicer.
///
/// Data flows one way: Session and the haptic thread's drill -> this -> SceneView; the menu ->
/// this -> Session. GUI thread only.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

#include <QObject>
#include <QString>

#include "vh/ui/view/tool_shadow.h"

class QAction;
class QMenu;
class QTimer;
class QWidget;

namespace vh::haptics {
class ScalarVolume;
}
namespace vh::runtime {
class Drill;
class HapticThread;
class Session;
struct DrilledCavity;
enum class SessionChange : std::uint32_t;
}  // namespace vh::runtime

namespace vh::ui {

class SceneView;

/// The picture's voxels (linear indices of the scan's grid, x fastest) of voxels removed from the
/// felt field (its linear indices): the same indices where the two grids agree, else the scan
/// voxel nearest to each removed voxel's centre (those outside the scan are dropped).
std::vector<std::uint64_t> pictureIndices(const haptics::ScalarVolume& felt, const haptics::ScalarVolume& scan,
                                          std::span<const std::uint64_t> felt_indices);

class DrillController : public QObject {
  Q_OBJECT

 public:
  /// Observes `session` from now on; `session` and `view` outlive this.
  DrillController(runtime::Session& session, SceneView& view, QObject* parent = nullptr);
  ~DrillController() override;

  /// Adds Haptics > Drill (checkable, Ctrl+B) to `haptics_menu` and File > Export Drilled Volume
  /// to `file_menu` (either may be null).
  void addMenuActions(QMenu* haptics_menu, QMenu* file_menu, QWidget* dialog_parent);
  /// Starts or stops the burr; a message says why when it cannot (no scene, a tool too small).
  void setDrilling(bool on);
  /// Moves the removed voxels to the picture now (the timer does it every 20 ms).
  void drain();
  /// Voxels of the felt field removed so far in this scene: the cavity the haptic threads'
  /// drill started from, plus those drained from it since.
  std::uint64_t removedVoxels() const noexcept { return removed_; }
  /// Removed volume so far [mm^3].
  double removed_mm3() const noexcept { return removed_mm3_; }
  /// Writes the drilled scan to `nrrd_path` (NRRD, the scan's type, LPS in mm) and the removed
  /// region as one segment "drilled" to `seg_path` (.seg.nrrd, 3D Slicer's keys).
  /// @throws std::runtime_error naming the file when nothing was drilled or a write fails.
  void exportDrilled(const std::filesystem::path& nrrd_path, const std::filesystem::path& seg_path) const;
  /// File > Export Drilled Volume: exportDrilled() to `nrrd_path` (".nrrd" added when missing)
  /// and the removed region beside it (NAME.seg.nrrd), telling the status bar (message()) that
  /// it is writing, then, when done, both files by name, the NRRD's size and the volume removed.
  /// @return the written NRRD's path. @throws std::runtime_error as exportDrilled().
  std::filesystem::path exportDrilledWithNotice(std::filesystem::path nrrd_path);
  /// The felt field as the hand feels it around the cavity (live().hapticField() carved by every
  /// voxel removed so far), for the tool's shadow; nothing carved before the first removal.
  const CarvedRegion& carved() const noexcept { return carved_; }

 signals:
  /// A short text for the status bar (on, off, critical removal).
  void message(const QString& text, int timeout_ms);
  /// The cavity grew or was replaced (carved() changed): the shadow is cast again.
  void cavityChanged();

 private:
  void onSessionChanged(runtime::SessionChange what);
  void reset();
  /// The picture shows `cavity` (null: none) removed, as a new drill starts from it: only the
  /// voxels it lacks are uploaded, unless it shows some the cavity lacks (then from the scan).
  void showCavity(const runtime::DrilledCavity* cavity, double removed_value);
  /// Alerts for the voxels of critical materials `drill` removed since the last report, each
  /// also a "critical_removed" event recorded through `thread` (null: none).
  void reportCritical(const runtime::Drill& drill, runtime::HapticThread* thread);

  runtime::Session& session_;
  SceneView& view_;
  int observer_ = 0;
  QTimer* timer_ = nullptr;
  QAction* action_ = nullptr;
  std::shared_ptr<runtime::Drill> drill_seen_;  // the drill whose log is drained (held: its last removals are told)
  std::vector<std::uint64_t> buffer_;           // drained felt-grid indices
  std::vector<std::uint64_t> image_indices_;    // the same on the picture's grid
  std::vector<std::uint8_t> removed_mask_;      // per voxel of the picture: 1 when removed
  std::vector<std::uint64_t> critical_seen_;    // per material: removed voxels already reported
  CarvedRegion carved_;                         // the felt field's voxels removed so far, for the shadow
  std::uint64_t removed_ = 0;
  double removed_mm3_ = 0.0;
};

}  // namespace vh::ui
