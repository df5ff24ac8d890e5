// The scene's volume mapper with box uploads (drillable_volume_mapper.h).
#include "drillable_volume_mapper.h"

#include <cstddef>

#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkObjectFactory.h>
#include <vtkOpenGLRenderWindow.h>
#include <vtkPointData.h>
#include <vtkRenderer.h>
#include <vtkTextureObject.h>
#include <vtkVolumeInputHelper.h>
#include <vtkVolumeTexture.h>
#include <vtk_glew.h>

namespace vh::ui {

vtkStandardNewMacro(DrillableVolumeMapper);

void DrillableVolumeMapper::GPURender(vtkRenderer* ren, vtkVolume* vol) {
  if (!partitioned_) partitionForTextureLimit(ren);
  if (pending_) uploadPending();
  Superclass::GPURender(ren, vol);
}

void DrillableVolumeMapper::partitionForTextureLimit(vtkRenderer* ren) {
  vtkImageData* image = vtkImageData::SafeDownCast(GetInput());
  auto* window = vtkOpenGLRenderWindow::SafeDownCast(ren->GetRenderWindow());
  if (image == nullptr || window == nullptr) return;
  partitioned_ = true;
  const int limit = vtkTextureObject::GetMaximumTextureSize3D(window);
  if (limit < 16) return;  // unknown: one texture, as VTK does
  int dims[3];
  image->GetDimensions(dims);
  for (int a = 0; a < 3; ++a) blocks[a] = std::max(1, (dims[a] + limit - 3) / (limit - 2));
  if (blocks[0] * blocks[1] * blocks[2] > 1)
    SetPartitions(static_cast<unsigned short>(blocks[0]), static_cast<unsigned short>(blocks[1]),
                  static_cast<unsigned short>(blocks[2]));
}

void DrillableVolumeMapper::uploadPending() {
  vtkImageData* image = vtkImageData::SafeDownCast(GetInput());
  const auto it = AssembledInputs.find(0);
  vtkTextureObject* texture = nullptr;
  if (image != nullptr && it != AssembledInputs.end() && it->second.Texture != nullptr &&
      it->second.Texture->GetCurrentBlock() != nullptr)
    texture = it->second.Texture->GetCurrentBlock()->TextureObject;
  vtkDataArray* scalars = image != nullptr ? image->GetPointData()->GetScalars() : nullptr;
  int dims[3] = {0, 0, 0};
  if (image != nullptr) image->GetDimensions(dims);
  const bool whole_block = texture != nullptr && texture->GetHandle() != 0 &&
                           static_cast<int>(texture->GetWidth()) == dims[0] &&
                           static_cast<int>(texture->GetHeight()) == dims[1] &&
                           static_cast<int>(texture->GetDepth()) == dims[2];
  if (!whole_block || scalars == nullptr || scalars->GetNumberOfComponents() != 1 ||
      texture->GetVTKDataType() != scalars->GetDataType()) {
    if (image != nullptr) image->Modified();  // VTK uploads the whole volume
    ++full_uploads;
    clearPending();
    return;
  }
  const int type = scalars->GetDataType();
  const int size = scalars->GetDataTypeSize();
  int lo[3], n[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::clamp(lo_[a], 0, dims[a] - 1);
    n[a] = std::clamp(hi_[a], 0, dims[a] - 1) - lo[a] + 1;
  }
  const auto* base = static_cast<const unsigned char*>(scalars->GetVoidPointer(0));
  const std::size_t offset =
      (static_cast<std::size_t>(lo[2]) * dims[1] * dims[0] + static_cast<std::size_t>(lo[1]) * dims[0] + lo[0]) * size;
  texture->Bind();
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, dims[0]);
  glPixelStorei(GL_UNPACK_IMAGE_HEIGHT, dims[1]);
  glTexSubImage3D(GL_TEXTURE_3D, 0, lo[0], lo[1], lo[2], n[0], n[1], n[2],
                  texture->GetFormat(type, 1, false), texture->GetDataType(type), base + offset);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  glPixelStorei(GL_UNPACK_IMAGE_HEIGHT, 0);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  ++partial_uploads;
  clearPending();
}

}  // namespace vh::ui
