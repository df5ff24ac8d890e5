#pragma once
// The scene's volume mapper (scene_actors.cpp): VTK's GPU ray caster with box uploads of the
// voxels drilling or soft tissue changed. Private to vh::ui's view.
#include <algorithm>
#include <array>
#include <cstdint>

#include <vtkOpenGLGPUVolumeRayCastMapper.h>
#include <vtkType.h>

namespace vh::ui {

/// VTK's GPU ray caster, plus one thing: a box of changed voxels (drilling, soft tissue) goes into
/// its volume texture with glTexSubImage3D before the next frame, instead of a re-upload of the
/// whole volume (VTK 9.1 re-uploads everything when the image is Modified()). The image's scalars are written
/// in place without Modified(); the box is sent where the texture is one block holding the
/// image's own scalar type (no partitions, no conversion); otherwise the image is Modified() and
/// VTK uploads it whole, as before.
class DrillableVolumeMapper : public vtkOpenGLGPUVolumeRayCastMapper {
 public:
  static DrillableVolumeMapper* New();
  vtkTypeMacro(DrillableVolumeMapper, vtkOpenGLGPUVolumeRayCastMapper)

  /// Adds the voxel box [lo, hi] (inclusive) to what the next frame uploads.
  void markChanged(const int lo[3], const int hi[3]) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = std::min(lo_[a], lo[a]);
      hi_[a] = std::max(hi_[a], hi[a]);
    }
    pending_ = true;
  }
  void clearPending() {
    pending_ = false;
    for (int a = 0; a < 3; ++a) lo_[a] = VTK_INT_MAX, hi_[a] = VTK_INT_MIN;
  }
  std::uint64_t partial_uploads = 0, full_uploads = 0;
  /// Blocks of the volume texture per axis (1 1 1: one texture), chosen at the first frame.
  std::array<int, 3> blocks{1, 1, 1};

 protected:
  void GPURender(vtkRenderer* ren, vtkVolume* vol) override;

 private:
  /// A volume longer than the GPU's 3-D texture limit on an axis (2048 on Mesa's llvmpipe and
  /// many GPUs: a 512 x 512 x 3000 whole-body CT) would be left blank by one texture: it goes
  /// into blocks instead, each within the limit, ray cast one after the other
  /// (vtkOpenGLGPUVolumeRayCastMapper::SetPartitions), before its first upload. The limit is
  /// GL_MAX_3D_TEXTURE_SIZE of the frame's context; the blocks share a voxel plane, so each holds
  /// at most limit - 2 voxels along an axis.
  void partitionForTextureLimit(vtkRenderer* ren);
  /// The pending box into the volume texture (glTexSubImage3D), or the whole image Modified().
  void uploadPending();

  bool pending_ = false;
  bool partitioned_ = false;
  int lo_[3] = {VTK_INT_MAX, VTK_INT_MAX, VTK_INT_MAX};
  int hi_[3] = {VTK_INT_MIN, VTK_INT_MIN, VTK_INT_MIN};
};

}  // namespace vh::ui
