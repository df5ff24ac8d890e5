#include "vh/ui/view/view_look.h"

#include <array>

#include <vtkRenderer.h>

#include "vh/ui/view/scene_actors.h"

namespace vh::ui {
namespace {

std::array<double, 3> rgbOf(const QColor& c) { return {c.redF(), c.greenF(), c.blueF()}; }

}  // namespace

void applyColours(vtkRenderer* renderer, SceneActors* actors, const ViewLook& look) {
  const auto bottom = rgbOf(look.background_bottom);
  const auto top = rgbOf(look.background_top);
  renderer->SetBackground(bottom[0], bottom[1], bottom[2]);
  renderer->SetBackground2(top[0], top[1], top[2]);
  if (actors == nullptr) return;
  const auto s = rgbOf(look.surface);
  const auto t = rgbOf(look.tool);
  const auto d = rgbOf(look.device);
  actors->setSurfaceColour(s[0], s[1], s[2]);
  actors->setToolColour(t[0], t[1], t[2]);
  actors->setDeviceColour(d[0], d[1], d[2]);
}

}  // namespace vh::ui
