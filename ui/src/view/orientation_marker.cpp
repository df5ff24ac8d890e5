#include "vh/ui/view/orientation_marker.h"

#include <algorithm>

#include <vtkAnnotatedCubeActor.h>
#include <vtkCallbackCommand.h>
#include <vtkCamera.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkTextProperty.h>

namespace vh::ui {

OrientationMarker::OrientationMarker(vtkRenderWindow* window, vtkRenderer* main) : window_(window), main_(main) {
  // Patient LPS: the face on +x is the patient's Left, +y Posterior, +z Superior.
  cube_->SetXPlusFaceText("L");
  cube_->SetXMinusFaceText("R");
  cube_->SetYPlusFaceText("P");
  cube_->SetYMinusFaceText("A");
  cube_->SetZPlusFaceText("S");
  cube_->SetZMinusFaceText("I");
  cube_->SetXFaceTextRotation(0);  // letters upright: sides seen with +z up, S and I with anterior up
  cube_->SetYFaceTextRotation(0);
  cube_->SetZFaceTextRotation(-90);
  cube_->SetFaceTextScale(0.65);
  cube_->GetCubeProperty()->SetColor(0.30, 0.34, 0.40);
  cube_->GetCubeProperty()->SetAmbient(0.3);
  cube_->GetTextEdgesProperty()->SetColor(0.85, 0.85, 0.85);
  cube_->GetTextEdgesProperty()->SetLineWidth(1.0);
  cube_->GetTextEdgesProperty()->SetDiffuse(0.0);
  cube_->GetTextEdgesProperty()->SetAmbient(1.0);
  // Left/Right red, Anterior/Posterior green, Superior/Inferior blue (the axes' usual colours).
  cube_->GetXPlusFaceProperty()->SetColor(0.95, 0.35, 0.30);
  cube_->GetXMinusFaceProperty()->SetColor(0.95, 0.35, 0.30);
  cube_->GetYPlusFaceProperty()->SetColor(0.40, 0.85, 0.40);
  cube_->GetYMinusFaceProperty()->SetColor(0.40, 0.85, 0.40);
  cube_->GetZPlusFaceProperty()->SetColor(0.40, 0.60, 1.00);
  cube_->GetZMinusFaceProperty()->SetColor(0.40, 0.60, 1.00);
  cube_->PickableOff();

  renderer_->AddViewProp(cube_);
  renderer_->SetViewport(0.0, 0.0, 0.14, 0.18);
  renderer_->InteractiveOff();
  renderer_->SetLayer(1);
  window_->SetNumberOfLayers(std::max(2, window_->GetNumberOfLayers()));
  window_->AddRenderer(renderer_);

  vtkNew<vtkCallbackCommand> sync;
  sync->SetClientData(this);
  sync->SetCallback([](vtkObject*, unsigned long, void* client, void*) {
    static_cast<OrientationMarker*>(client)->syncCamera();
  });
  observer_ = main_->AddObserver(vtkCommand::StartEvent, sync);
  syncCamera();
}

OrientationMarker::~OrientationMarker() {
  main_->RemoveObserver(observer_);
  window_->RemoveRenderer(renderer_);
}

void OrientationMarker::setVisible(bool visible) { renderer_->SetDraw(visible ? 1 : 0); }
bool OrientationMarker::visible() const { return renderer_->GetDraw() != 0; }

void OrientationMarker::syncCamera() {
  // Same direction and up as the main camera, at a fixed distance from the cube.
  vtkCamera* from = main_->GetActiveCamera();
  vtkCamera* to = renderer_->GetActiveCamera();
  double dop[3], up[3];
  from->GetDirectionOfProjection(dop);
  from->GetViewUp(up);
  constexpr double kDistance = 3.6;
  to->SetFocalPoint(0.0, 0.0, 0.0);
  to->SetPosition(-kDistance * dop[0], -kDistance * dop[1], -kDistance * dop[2]);
  to->SetViewUp(up);
  to->SetViewAngle(30.0);
  to->ParallelProjectionOff();
  renderer_->ResetCameraClippingRange();
}

}  // namespace vh::ui
