// Transfer functions of the rendering modes (ui/render_presets.h).
#include "vh/ui/view/render_presets.h"

#include <gtest/gtest.h>

namespace vh::ui {
namespace {

template <typename Points>
void expectIncreasingWithin(const Points& pts, double lo, double hi) {
  ASSERT_GE(pts.size(), 2u);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_GE(pts[i].value, lo);
    EXPECT_LE(pts[i].value, hi);
    if (i > 0) {
      EXPECT_GT(pts[i].value, pts[i - 1].value);
    }
  }
}

double opacityAt(const VolumeLook& look, double v) {
  const auto& o = look.opacity;
  if (v <= o.front().value) return o.front().opacity;
  for (std::size_t i = 1; i < o.size(); ++i) {
    if (v <= o[i].value) {
      const double t = (v - o[i - 1].value) / (o[i].value - o[i - 1].value);
      return o[i - 1].opacity + t * (o[i].opacity - o[i - 1].opacity);
    }
  }
  return o.back().opacity;
}

TEST(RenderPresets, CtPresetsSeparateTissueClassesInHu) {
  const VolumeLook bone = compositeLook(VolumePreset::kBone, -1024, 3071, true);
  expectIncreasingWithin(bone.colour, -1024, 3071);
  expectIncreasingWithin(bone.opacity, -1024, 3071);
  EXPECT_EQ(opacityAt(bone, -1000), 0.0) << "air transparent";
  EXPECT_EQ(opacityAt(bone, 40), 0.0) << "soft tissue transparent in the bone preset";
  EXPECT_GT(opacityAt(bone, 1000), 0.5) << "bone opaque";

  const VolumeLook soft = compositeLook(VolumePreset::kSoftTissue, -1024, 3071, true);
  EXPECT_GT(opacityAt(soft, 40), 0.0);
  EXPECT_LT(opacityAt(soft, 40), 0.2) << "soft tissue translucent";
  const VolumeLook skin = compositeLook(VolumePreset::kSkin, -1024, 3071, true);
  EXPECT_EQ(opacityAt(skin, -1000), 0.0);
  EXPECT_GT(opacityAt(skin, -300), 0.8) << "the air/skin boundary is a surface";
}

TEST(RenderPresets, PresetsClampToTheDataRangeAndMapForOtherUnits) {
  // CT stored without the air below -200 HU: points collapse onto the range, stay increasing.
  const VolumeLook clipped = compositeLook(VolumePreset::kBone, -200, 1500, true);
  expectIncreasingWithin(clipped.opacity, -200, 1500);
  expectIncreasingWithin(clipped.colour, -200, 1500);
  // Unitless 0..255 data: the HU axis is mapped onto the range.
  const VolumeLook mapped = compositeLook(VolumePreset::kBone, 0, 255, false);
  expectIncreasingWithin(mapped.opacity, 0, 255);
  EXPECT_EQ(opacityAt(mapped, 10), 0.0);
  EXPECT_GT(opacityAt(mapped, 250), 0.5);
}

TEST(RenderPresets, MipAndIsosurfaceLooks) {
  const VolumeLook mip = mipLook(-1024, 3071, true);
  expectIncreasingWithin(mip.opacity, -1024, 3071);
  EXPECT_FALSE(mip.shade);
  EXPECT_EQ(opacityAt(mip, -500), 0.0);
  EXPECT_EQ(opacityAt(mip, 2000), 1.0);
  const VolumeLook iso = isosurfaceLook(0, 10, 0.1, 0.2, 0.3);
  ASSERT_EQ(iso.colour.size(), 2u);
  EXPECT_EQ(iso.colour[0].g, 0.2);
  EXPECT_EQ(opacityAt(iso, 5), 1.0);
  EXPECT_EQ(modeName(RenderMode::kMip), "MIP");
  EXPECT_EQ(presetName(VolumePreset::kSoftTissue), "Soft tissue");
}

}  // namespace
}  // namespace vh::ui
