// Conversions between VTK images and haptics::ScalarVolume.
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <unordered_map>
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
  double value_scale = 1.0;  ///< F = value_scale * voxel + value_offset.
  double value_offset = 0.0;
};

bool isInteger(double v) { return std::isfinite(v) && v == std::round(v); }

/// True for F = scale * v + offset with integer scale (not 0) and offset, other than the identity.
bool integerRescale(double scale, double offset) {
  return isInteger(scale) && isInteger(offset) && scale != 0.0 && !(scale == 1.0 && offset == 0.0);
}

/// True when F = scale * v + offset, v in [lo, hi], is an integer rescale that lands in int16:
/// the values in data units can then be stored as int16 exactly.
bool rescaleFitsInt16(double scale, double offset, double lo, double hi) {
  if (!integerRescale(scale, offset)) return false;
  const double a = scale * lo + offset, b = scale * hi + offset;
  return std::min(a, b) >= std::numeric_limits<std::int16_t>::min() &&
         std::max(a, b) <= std::numeric_limits<std::int16_t>::max();
}

/// Writes scale * src[i] + offset as int16 into out[i] (byte buffers; `out` may be `src` when
/// Src is 2 bytes wide: each value is read before it is overwritten).
template <typename Src>
void rescaleToInt16(const std::byte* src, std::size_t n, double scale, double offset, std::byte* out) {
  for (std::size_t i = 0; i < n; ++i) {
    Src v;
    std::memcpy(&v, src + i * sizeof(Src), sizeof(Src));
    const auto hu = static_cast<std::int16_t>(std::lround(scale * static_cast<double>(v) + offset));
    std::memcpy(out + i * sizeof(std::int16_t), &hu, sizeof(hu));
  }
}

template <typename T>
void rangeOf(const std::byte* bytes, std::size_t n, double& lo, double& hi) {
  T a = std::numeric_limits<T>::max(), b = std::numeric_limits<T>::lowest();
  for (std::size_t i = 0; i < n; ++i) {
    T v;
    std::memcpy(&v, bytes + i * sizeof(T), sizeof(T));
    a = std::min(a, v);
    b = std::max(b, v);
  }
  lo = static_cast<double>(a);
  hi = static_cast<double>(b);
}

/// An integer rescale of integer voxels (a CT's RescaleIntercept) applied to `v` in place, when
/// the values in data units fit int16: then the field holds data units (scale 1, offset 0) and
/// the rendering image can share its buffer instead of holding a rescaled copy. uint8 voxels
/// are widened (a new buffer); int16 and uint16 are rewritten where they are.
void applyIntegerRescale(ConvertedVoxels& v) {
  const std::size_t n = v.bytes.size() / haptics::voxelTypeSize(v.type);
  if (v.type == VoxelType::kFloat32 || n == 0 || !integerRescale(v.value_scale, v.value_offset)) return;
  double lo = 0.0, hi = 0.0;
  switch (v.type) {
    case VoxelType::kUInt8: rangeOf<std::uint8_t>(v.bytes.data(), n, lo, hi); break;
    case VoxelType::kInt16: rangeOf<std::int16_t>(v.bytes.data(), n, lo, hi); break;
    case VoxelType::kUInt16: rangeOf<std::uint16_t>(v.bytes.data(), n, lo, hi); break;
    case VoxelType::kFloat32: return;
  }
  if (!rescaleFitsInt16(v.value_scale, v.value_offset, lo, hi)) return;
  switch (v.type) {
    case VoxelType::kUInt8: {
      std::vector<std::byte> wide(n * sizeof(std::int16_t));
      rescaleToInt16<std::uint8_t>(v.bytes.data(), n, v.value_scale, v.value_offset, wide.data());
      v.bytes = std::move(wide);
      break;
    }
    case VoxelType::kInt16:
      rescaleToInt16<std::int16_t>(v.bytes.data(), n, v.value_scale, v.value_offset, v.bytes.data());
      break;
    case VoxelType::kUInt16:
      rescaleToInt16<std::uint16_t>(v.bytes.data(), n, v.value_scale, v.value_offset, v.bytes.data());
      break;
    case VoxelType::kFloat32: return;
  }
  v.type = VoxelType::kInt16;
  v.value_scale = 1.0;
  v.value_offset = 0.0;
}

/// Copies (or converts) the scalars into one of the field's voxel types. int8 -> int16; wider
/// integers -> int16 or uint16 when their range fits, else float32; double -> float32. An
/// integer rescale whose data units fit int16 is applied on the way (applyIntegerRescale()).
ConvertedVoxels toFieldVoxels(vtkDataArray* array, std::size_t n, double value_scale, double value_offset) {
  ConvertedVoxels out;
  out.value_scale = value_scale;
  out.value_offset = value_offset;
  const int t = array->GetDataType();
  double range[2] = {0.0, 0.0};
  const bool ranged = isIntegralVtkType(t) && integerRescale(value_scale, value_offset);
  if (ranged) array->GetRange(range, 0);
  if (ranged && rescaleFitsInt16(value_scale, value_offset, range[0], range[1])) {
    // Straight into data units: one pass, no copy of the stored values in between.
    out.type = VoxelType::kInt16;
    out.bytes.resize(n * sizeof(std::int16_t));
    const auto* src = static_cast<const std::byte*>(array->GetVoidPointer(0));
    switch (t) {
      vtkTemplateMacro(rescaleToInt16<VTK_TT>(src, n, value_scale, value_offset, out.bytes.data()));
      default:
        throw std::invalid_argument(std::string("unsupported VTK scalar type ") + array->GetDataTypeAsString());
    }
    out.value_scale = 1.0;
    out.value_offset = 0.0;
    return out;
  }
  if (const auto direct = detail::fieldVoxelTypeOf(t)) {
    out.type = *direct;
    out.bytes.resize(n * haptics::voxelTypeSize(*direct));
    std::memcpy(out.bytes.data(), array->GetVoidPointer(0), out.bytes.size());
    return out;
  }
  if (!ranged) array->GetRange(range, 0);
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

}  // namespace

ImagePtr shareImage(vtkImageData* image) {
  if (image == nullptr) return nullptr;
  image->Register(nullptr);
  return ImagePtr(image, [](vtkImageData* p) { p->UnRegister(nullptr); });
}

namespace {

/// The fields whose voxel buffers images wrap, each entry held by one wrapping VTK array: a VTK
/// array's free function is a plain function of the buffer's address, so the owner it keeps
/// alive is found here by that address (one entry per wrapping array; several arrays may wrap
/// one field, and all of them hold it).
std::mutex g_wrapped_mutex;
std::unordered_multimap<const void*, std::shared_ptr<const haptics::ScalarVolume>> g_wrapped;

/// The free function of a wrapping array: called by VTK when the array lets go of `buffer`
/// (destroyed, resized or given another buffer); releases that array's hold on the field.
void releaseWrappedField(void* buffer) {
  std::shared_ptr<const haptics::ScalarVolume> released;  // destroyed outside the lock
  const std::lock_guard<std::mutex> lock(g_wrapped_mutex);
  const auto it = g_wrapped.find(buffer);
  if (it == g_wrapped.end()) return;
  released = std::move(it->second);
  g_wrapped.erase(it);
}

/// An image with the field's geometry (metres, no direction) and no scalars yet.
vtkSmartPointer<vtkImageData> imageWithGeometryOf(const haptics::ScalarVolume& field) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  const auto& g = field.geometry();
  image->SetDimensions(g.dims[0], g.dims[1], g.dims[2]);
  image->SetSpacing(g.spacing_m.x(), g.spacing_m.y(), g.spacing_m.z());
  image->SetOrigin(g.origin_W_m.x(), g.origin_W_m.y(), g.origin_W_m.z());
  return image;
}

}  // namespace

ImagePtr imageFromField(const haptics::ScalarVolume& field) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  if (field.empty()) return shareImage(image);
  image = imageWithGeometryOf(field);
  const std::size_t n = field.geometry().voxelCount();
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

ImagePtr imageFromField(const std::shared_ptr<const haptics::ScalarVolume>& field) {
  if (field == nullptr) return imageFromField(haptics::ScalarVolume());
  if (field->empty() || field->valueScale() != 1.0 || field->valueOffset() != 0.0) return imageFromField(*field);
  // The image's scalars are the field's own buffer: VTK's array does not free it (its free
  // function releases the array's hold on the field instead), so the voxels live as long as
  // the field's last holder, VTK's included. Never written through the image (const field).
  vtkSmartPointer<vtkDataArray> scalars;
  scalars.TakeReference(vtkDataArray::CreateDataArray(vtkTypeOf(field->voxelType())));
  scalars->SetNumberOfComponents(1);
  void* buffer = const_cast<std::byte*>(field->bytes().data());
  {
    const std::lock_guard<std::mutex> lock(g_wrapped_mutex);
    g_wrapped.emplace(buffer, field);
  }
  scalars->SetVoidArray(buffer, static_cast<vtkIdType>(field->geometry().voxelCount()), /*save=*/0,
                        vtkAbstractArray::VTK_DATA_ARRAY_USER_DEFINED);
  scalars->SetArrayFreeFunction(&releaseWrappedField);
  scalars->SetName("values");
  auto image = imageWithGeometryOf(*field);
  image->GetPointData()->SetScalars(scalars);
  return shareImage(image);
}

namespace detail {

std::optional<VoxelType> fieldVoxelTypeOf(int vtk_type) {
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

LoadedVolume finishVolume(RawVolume raw, const fs::path& path) {
  ConvertedVoxels voxels;
  voxels.value_scale = raw.value_scale;
  voxels.value_offset = raw.value_offset;
  if (raw.image != nullptr) {
    // A reader's vtkImageData (in this process): validated, then copied or converted once into
    // the field's voxels, and released.
    int d[3] = {0, 0, 0};
    raw.image->GetDimensions(d);
    raw.geometry.dims = {d[0], d[1], d[2]};
  }
  const std::array<int, 3> dims = raw.geometry.dims;
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2) {
    fail(path, "not a 3-D volume: " + dimsString(dims) +
                   " voxels (at least 2 are needed along each axis)");
  }
  const std::size_t n = raw.geometry.voxelCount();
  if (raw.image != nullptr) {
    vtkDataArray* scalars = raw.image->GetPointData()->GetScalars();
    if (scalars == nullptr || scalars->GetNumberOfTuples() == 0) {
      fail(path, "no voxel data was read (" + dimsString(dims) + " expected)");
    }
    if (scalars->GetNumberOfComponents() != 1) {
      fail(path, "has " + std::to_string(scalars->GetNumberOfComponents()) +
                     " components per voxel; only scalar (one-component) volumes are supported");
    }
    if (static_cast<std::size_t>(scalars->GetNumberOfTuples()) != n) {
      fail(path, "voxel data has " + std::to_string(scalars->GetNumberOfTuples()) +
                     " values where " + dimsString(dims) + " = " + std::to_string(n) +
                     " were expected");
    }
    try {
      voxels = toFieldVoxels(scalars, n, raw.value_scale, raw.value_offset);
    } catch (const std::exception& e) {
      fail(path, e.what());
    }
    // The reader's voxels are in the field's buffer now: released before anything else is
    // made (a scan peaks at two copies of its voxels here, and keeps one).
    raw.image = nullptr;
  } else {
    // Voxels taken back from the reader process: they become the field's, rescaled in place.
    if (raw.voxels.empty()) fail(path, "no voxel data was read (" + dimsString(dims) + " expected)");
    if (raw.voxels.size() != n * haptics::voxelTypeSize(raw.voxel_type)) {
      fail(path, "voxel data has " + std::to_string(raw.voxels.size()) + " bytes where " + dimsString(dims) +
                     " voxels of " + haptics::voxelTypeName(raw.voxel_type) + " were expected");
    }
    voxels.type = raw.voxel_type;
    voxels.bytes = std::move(raw.voxels);
    applyIntegerRescale(voxels);
  }

  auto field = std::make_shared<haptics::ScalarVolume>();
  try {
    *field = haptics::ScalarVolume::FromBytes(raw.geometry, voxels.type, std::move(voxels.bytes),
                                              voxels.value_scale, voxels.value_offset);
  } catch (const std::exception& e) {
    fail(path, std::string("invalid volume: ") + e.what());
  }

  LoadedVolume out;
  out.field = std::move(field);
  out.image = imageFromField(out.field);  // the field's own voxels when they are in data units
  out.info = std::move(raw.info);
  out.info.source = path;
  return out;
}

}  // namespace detail
}  // namespace vh::io
