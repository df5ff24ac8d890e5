// Conversions between VTK images and haptics::ScalarVolume.
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <cstring>
#include <limits>
#include <stdexcept>

#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkShortArray.h>
#include <vtkType.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnsignedShortArray.h>

#include "loader_internal.h"
#include "vh/io/volume_loader.h"

namespace vh::io {
namespace {

using haptics::VoxelType;

/// VTK array type that stores a field voxel type as is.
int vtkTypeOf(VoxelType type) {
  switch (type) {
    case VoxelType::kUInt8:
      return VTK_UNSIGNED_CHAR;
    case VoxelType::kInt16:
      return VTK_SHORT;
    case VoxelType::kUInt16:
      return VTK_UNSIGNED_SHORT;
    case VoxelType::kFloat32:
      return VTK_FLOAT;
  }
  return VTK_FLOAT;
}

/// Field voxel type stored by a VTK scalar type as is, if any.
std::optional<VoxelType> voxelTypeOf(int vtk_type) {
  switch (vtk_type) {
    case VTK_UNSIGNED_CHAR:
      return VoxelType::kUInt8;
    case VTK_SHORT:
      return VoxelType::kInt16;
    case VTK_UNSIGNED_SHORT:
      return VoxelType::kUInt16;
    case VTK_FLOAT:
      return VoxelType::kFloat32;
    default:
      return std::nullopt;
  }
}

bool isIntegralVtkType(int vtk_type) {
  return vtk_type != VTK_FLOAT && vtk_type != VTK_DOUBLE;
}

template <typename Dst, typename Src>
void convertValues(const Src* src, std::size_t n, std::byte* out) {
  for (std::size_t i = 0; i < n; ++i) {
    const Dst v = static_cast<Dst>(src[i]);
    std::memcpy(out + i * sizeof(Dst), &v, sizeof(Dst));
  }
}

template <typename Dst>
void convertArray(vtkDataArray* array, std::size_t n, std::byte* out) {
  void* src = array->GetVoidPointer(0);
  switch (array->GetDataType()) {
    vtkTemplateMacro(convertValues<Dst>(static_cast<const VTK_TT*>(src), n, out));
    default:
      throw std::invalid_argument(std::string("unsupported VTK scalar type ") +
                                  array->GetDataTypeAsString());
  }
}

struct ConvertedVoxels {
  VoxelType type = VoxelType::kFloat32;
  std::vector<std::byte> bytes;
  bool converted = false;  ///< True when the stored type was changed.
};

/// Copies (or converts) the scalars into one of the field's voxel types. int8 -> int16; wider
/// integers -> int16 or uint16 when their range fits, else float32; double -> float32.
ConvertedVoxels toFieldVoxels(vtkDataArray* array, std::size_t n) {
  ConvertedVoxels out;
  if (const auto direct = voxelTypeOf(array->GetDataType())) {
    out.type = *direct;
    out.bytes.resize(n * haptics::voxelTypeSize(*direct));
    std::memcpy(out.bytes.data(), array->GetVoidPointer(0), out.bytes.size());
    return out;
  }
  out.converted = true;
  double range[2] = {0.0, 0.0};
  array->GetRange(range, 0);
  const int t = array->GetDataType();
  if (isIntegralVtkType(t) && range[0] >= std::numeric_limits<std::int16_t>::min() &&
      range[1] <= std::numeric_limits<std::int16_t>::max()) {
    out.type = VoxelType::kInt16;
    out.bytes.resize(n * sizeof(std::int16_t));
    convertArray<std::int16_t>(array, n, out.bytes.data());
  } else if (isIntegralVtkType(t) && range[0] >= 0.0 &&
             range[1] <= std::numeric_limits<std::uint16_t>::max()) {
    out.type = VoxelType::kUInt16;
    out.bytes.resize(n * sizeof(std::uint16_t));
    convertArray<std::uint16_t>(array, n, out.bytes.data());
  } else {
    out.type = VoxelType::kFloat32;
    out.bytes.resize(n * sizeof(float));
    convertArray<float>(array, n, out.bytes.data());
  }
  return out;
}

template <typename T>
T loadAt(const std::byte* bytes, std::size_t i) {
  T v;
  std::memcpy(&v, bytes + i * sizeof(T), sizeof(T));
  return v;
}

/// Raw voxel i of the field, as a double.
double rawAt(VoxelType type, const std::byte* bytes, std::size_t i) {
  switch (type) {
    case VoxelType::kUInt8:
      return loadAt<std::uint8_t>(bytes, i);
    case VoxelType::kInt16:
      return loadAt<std::int16_t>(bytes, i);
    case VoxelType::kUInt16:
      return loadAt<std::uint16_t>(bytes, i);
    case VoxelType::kFloat32:
      return loadAt<float>(bytes, i);
  }
  return 0.0;
}

bool isInteger(double v) { return std::isfinite(v) && v == std::round(v); }

}  // namespace

ImagePtr shareImage(vtkImageData* image) {
  if (image == nullptr) return nullptr;
  image->Register(nullptr);
  return ImagePtr(image, [](vtkImageData* p) { p->UnRegister(nullptr); });
}

ImagePtr imageFromField(const haptics::ScalarVolume& field) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  if (field.empty()) return shareImage(image);
  const auto& g = field.geometry();
  image->SetDimensions(g.dims[0], g.dims[1], g.dims[2]);
  image->SetSpacing(g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z());
  image->SetOrigin(g.origin_W_m.x(), g.origin_W_m.y(), g.origin_W_m.z());
  const std::size_t n = g.voxelCount();
  const std::byte* bytes = field.bytes().data();
  const double scale = field.valueScale();
  const double offset = field.valueOffset();

  vtkSmartPointer<vtkDataArray> scalars;
  if (scale == 1.0 && offset == 0.0) {
    scalars.TakeReference(vtkDataArray::CreateDataArray(vtkTypeOf(field.voxelType())));
    scalars->SetNumberOfComponents(1);
    scalars->SetNumberOfTuples(static_cast<vtkIdType>(n));
    std::memcpy(scalars->GetVoidPointer(0), bytes, field.bytes().size());
  } else if (field.voxelType() != VoxelType::kFloat32 && isInteger(scale) && isInteger(offset) &&
             field.minValue() >= std::numeric_limits<std::int16_t>::min() &&
             field.maxValue() <= std::numeric_limits<std::int16_t>::max()) {
    auto shorts = vtkSmartPointer<vtkShortArray>::New();
    shorts->SetNumberOfTuples(static_cast<vtkIdType>(n));
    std::int16_t* out = shorts->GetPointer(0);
    for (std::size_t i = 0; i < n; ++i) {
      out[i] = static_cast<std::int16_t>(
          std::lround(scale * rawAt(field.voxelType(), bytes, i) + offset));
    }
    scalars = shorts;
  } else {
    auto floats = vtkSmartPointer<vtkFloatArray>::New();
    floats->SetNumberOfTuples(static_cast<vtkIdType>(n));
    float* out = floats->GetPointer(0);
    for (std::size_t i = 0; i < n; ++i) {
      out[i] = static_cast<float>(scale * rawAt(field.voxelType(), bytes, i) + offset);
    }
    scalars = floats;
  }
  scalars->SetName("values");
  image->GetPointData()->SetScalars(scalars);
  return shareImage(image);
}

namespace detail {

LoadedVolume finishVolume(RawVolume raw, const fs::path& path) {
  if (raw.image == nullptr) fail(path, "the reader produced no image");
  int d[3] = {0, 0, 0};
  raw.image->GetDimensions(d);
  const std::array<int, 3> dims{d[0], d[1], d[2]};
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2) {
    fail(path, "not a 3-D volume: " + dimsString(dims) +
                   " voxels (at least 2 are needed along each axis)");
  }
  vtkDataArray* scalars = raw.image->GetPointData()->GetScalars();
  if (scalars == nullptr || scalars->GetNumberOfTuples() == 0) {
    fail(path, "no voxel data was read (" + dimsString(dims) + " expected)");
  }
  if (scalars->GetNumberOfComponents() != 1) {
    fail(path, "has " + std::to_string(scalars->GetNumberOfComponents()) +
                   " components per voxel; only scalar (one-component) volumes are supported");
  }
  raw.geometry.dims = dims;
  const std::size_t n = raw.geometry.voxelCount();
  if (static_cast<std::size_t>(scalars->GetNumberOfTuples()) != n) {
    fail(path, "voxel data has " + std::to_string(scalars->GetNumberOfTuples()) +
                   " values where " + dimsString(dims) + " = " + std::to_string(n) +
                   " were expected");
  }

  ConvertedVoxels voxels;
  try {
    voxels = toFieldVoxels(scalars, n);
  } catch (const std::exception& e) {
    fail(path, e.what());
  }
  const bool keep_image = !voxels.converted && raw.value_scale == 1.0 && raw.value_offset == 0.0;
  vtkSmartPointer<vtkDataArray> kept_scalars = keep_image ? scalars : nullptr;
  // The reader's voxels are in the field now: release them before the rendering image is made
  // (a 1 GB scan peaks at two copies of its voxels, not three).
  scalars = nullptr;
  raw.image = nullptr;

  auto field = std::make_shared<haptics::ScalarVolume>();
  try {
    *field = haptics::ScalarVolume::FromBytes(raw.geometry, voxels.type, std::move(voxels.bytes),
                                              raw.value_scale, raw.value_offset);
  } catch (const std::exception& e) {
    fail(path, std::string("invalid volume: ") + e.what());
  }

  LoadedVolume out;
  if (keep_image) {
    // Share the reader's voxel array; only the geometry changes (metres, no direction).
    out.image = shareImage(vtkSmartPointer<vtkImageData>::New());
    out.image->SetDimensions(dims[0], dims[1], dims[2]);
    const auto& g = field->geometry();
    out.image->SetSpacing(g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z());
    out.image->SetOrigin(g.origin_W_m.x(), g.origin_W_m.y(), g.origin_W_m.z());
    if (kept_scalars->GetName() == nullptr) kept_scalars->SetName("values");
    out.image->GetPointData()->SetScalars(kept_scalars);
  } else {
    out.image = imageFromField(*field);
  }
  out.field = std::move(field);
  out.info = std::move(raw.info);
  out.info.source = path;
  return out;
}

}  // namespace detail
}  // namespace vh::io
