#pragma once
/// @file
/// The patient orientation marker: a cube labelled with the patient directions of W (patient
/// LPS: +x Left, +y Posterior, +z Superior) drawn in a corner of the view, turning with the main
/// camera. Its own small renderer on layer 1 of the render window; no Qt, no interactor.

#include <vtkNew.h>

class vtkAnnotatedCubeActor;
class vtkAxesActor;
class vtkPropAssembly;
class vtkRenderer;
class vtkRenderWindow;

namespace vh::ui {

class OrientationMarker {
 public:
  /// Adds the marker's renderer to `window`; it follows `main`'s active camera at every render.
  OrientationMarker(vtkRenderWindow* window, vtkRenderer* main);
  ~OrientationMarker();
  OrientationMarker(const OrientationMarker&) = delete;
  OrientationMarker& operator=(const OrientationMarker&) = delete;

  void setVisible(bool visible);
  bool visible() const;
  /// The marker's renderer (viewport in the lower left corner).
  vtkRenderer* renderer() const noexcept { return renderer_; }

 private:
  void syncCamera();

  vtkRenderWindow* window_;  // not owned
  vtkRenderer* main_;        // not owned
  vtkNew<vtkRenderer> renderer_;
  vtkNew<vtkAnnotatedCubeActor> cube_;
  unsigned long observer_ = 0;
};

}  // namespace vh::ui
