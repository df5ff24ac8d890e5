#include "vh/ui/view/expert_ghost.h"

#include <vtkActor.h>
#include <vtkAlgorithmOutput.h>
#include <vtkCellArray.h>
#include <vtkMatrix4x4.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>

namespace vh::ui {

ExpertGhost::ExpertGhost(vtkRenderer* layer, vtkAlgorithmOutput* tool_T) : layer_(layer) {
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputConnection(tool_T);
  mapper->ScalarVisibilityOff();
  tool_->SetMapper(mapper);
  vtkProperty* p = tool_->GetProperty();
  p->SetColor(kRgb[0], kRgb[1], kRgb[2]);
  p->SetOpacity(kOpacity);
  p->SetAmbient(0.35);
  p->SetDiffuse(0.65);
  p->SetSpecular(0.0);
  p->BackfaceCullingOn();
  tool_->PickableOff();
  tool_->VisibilityOff();
  vtkNew<vtkMatrix4x4> m;
  tool_->SetUserMatrix(m);
  layer_->AddActor(tool_);

  path_points_->SetDataTypeToDouble();
  path_poly_->SetPoints(path_points_);
  vtkNew<vtkCellArray> lines;
  path_poly_->SetLines(lines);
  vtkNew<vtkPolyDataMapper> path_mapper;
  path_mapper->SetInputData(path_poly_);
  path_actor_->SetMapper(path_mapper);
  path_actor_->GetProperty()->SetColor(kRgb[0], kRgb[1], kRgb[2]);
  path_actor_->GetProperty()->SetOpacity(0.6);
  path_actor_->GetProperty()->SetLineWidth(1.0);
  path_actor_->GetProperty()->LightingOff();
  path_actor_->PickableOff();
  path_actor_->VisibilityOff();
  layer_->AddActor(path_actor_);
}

ExpertGhost::~ExpertGhost() {
  layer_->RemoveActor(tool_);
  layer_->RemoveActor(path_actor_);
}

void ExpertGhost::setPath(const haptics::GuidancePath* path) {
  hide();
  const std::size_t n = path == nullptr ? 0 : path->size();
  path_points_->SetNumberOfPoints(static_cast<vtkIdType>(2 * n));
  vtkNew<vtkCellArray> lines;
  lines->AllocateExact(static_cast<vtkIdType>(n), static_cast<vtkIdType>(2 * n));
  for (std::size_t i = 0; i < n; ++i) {
    const haptics::GuidancePath::Segment& s = path->segments()[i];
    const auto a = static_cast<vtkIdType>(2 * i);
    path_points_->SetPoint(a, s.a_W_m.x(), s.a_W_m.y(), s.a_W_m.z());
    path_points_->SetPoint(a + 1, s.b_W_m.x(), s.b_W_m.y(), s.b_W_m.z());
    const vtkIdType ids[2] = {a, a + 1};
    lines->InsertNextCell(2, ids);
  }
  path_points_->Modified();
  path_poly_->SetLines(lines);
  path_poly_->Modified();
  has_path_ = n > 0;
}

void ExpertGhost::show(const haptics::Pose& X_WE) {
  X_WE_ = X_WE;
  vtkMatrix4x4* m = tool_->GetUserMatrix();
  const Eigen::Matrix3d R = X_WE.R_AB.normalized().toRotationMatrix();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m->SetElement(r, c, R(r, c));
    m->SetElement(r, 3, X_WE.p_AB_m(r));
    m->SetElement(3, r, 0.0);
  }
  m->SetElement(3, 3, 1.0);
  m->Modified();
  tool_->Modified();
  tool_->VisibilityOn();
  path_actor_->SetVisibility(has_path_);
  visible_ = true;
}

void ExpertGhost::hide() {
  tool_->VisibilityOff();
  path_actor_->VisibilityOff();
  visible_ = false;
}

}  // namespace vh::ui
