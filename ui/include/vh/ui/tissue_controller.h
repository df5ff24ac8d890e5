#pragma once
/// @file
/// Soft tissue in the GUI: the Tissue dock and the deformation in the picture.
///
/// The dock says what yields (each band of the scan's values, its material with Young's modulus,
/// Poisson's ratio and the source of the figures, the lattice, the isovalue the tissue was built
/// for) and, while the hand presses, how far the surface gave (the indentation), how hard the
/// tissue is pushed and whether the proxy holds part of the spring-back off
/// (tissue::DeformedWindow). The picture shows the tissue as it is felt: the haptic thread's
/// deformable scene publishes the box of voxels it rewrote (the felt field F(X(p)), at most every
/// 10 ms while it changes, and the state it settles in); drained every 20 ms into the view's
/// private copy of the image (SceneActors::showVoxelBox(), which uploads only the box), so the
/// ray-cast isosurface the eyes see is the one the hand feels. A scene without tissue starts
/// none of it: no timer runs and the dock stays hidden.
///
/// Data flows one way: Session and the haptic thread's deformable scene -> this -> SceneView and
/// the dock. GUI thread only.

#include <cstdint>
#include <memory>

#include <QObject>

#include "vh/tissue/deformable_scene.h"

class QCheckBox;
class QDockWidget;
class QLabel;
class QMainWindow;
class QTableWidget;
class QTimer;

namespace vh::runtime {
class Session;
enum class SessionChange : std::uint32_t;
}  // namespace vh::runtime

namespace vh::ui {

class SceneView;

class TissueController : public QObject {
  Q_OBJECT

 public:
  /// Observes `session` from now on; adds the Tissue dock to `window` (hidden until a scene has
  /// tissue). `session`, `view` and `window` outlive this.
  TissueController(runtime::Session& session, SceneView& view, QMainWindow* window);
  ~TissueController() override;

  QDockWidget* dock() const noexcept { return dock_; }
  /// Takes the latest deformed window from the haptic thread into the picture and the dock now
  /// (the timer does it every 20 ms while the scene has tissue).
  void drain();
  /// The latest window shown (empty: the tissue at rest, or no tissue).
  const tissue::DeformedWindow& shown() const noexcept { return window_; }
  /// Windows drained into the picture since the scene was set.
  std::uint64_t windowsShown() const noexcept { return windows_shown_; }
  /// Whether the picture follows the deformation (the dock's check box; on by default).
  bool showingDeformation() const noexcept;

 signals:
  void message(const QString& text, int timeout_ms);

 private:
  void onSessionChanged(runtime::SessionChange what);
  void describeScene();
  void showFigures();
  void backToRest();

  runtime::Session& session_;
  SceneView& view_;
  int observer_ = 0;
  QDockWidget* dock_ = nullptr;
  QLabel* summary_ = nullptr;
  QTableWidget* bands_ = nullptr;
  QLabel* live_ = nullptr;
  QCheckBox* show_ = nullptr;
  QTimer* timer_ = nullptr;
  const tissue::DeformableScene* scene_seen_ = nullptr;  // the haptic thread's scene last drained
  tissue::DeformedWindow window_;
  std::uint64_t windows_shown_ = 0;
  bool told_mismatch_ = false;
  double deepest_m_ = 0.0;  // the deepest indentation since the scene was set
};

}  // namespace vh::ui
