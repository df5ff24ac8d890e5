#include "vh/ui/drill_controller.h"

#include <array>
#include <cmath>
#include <stdexcept>

#include <QAction>
#include <QCoreApplication>
#include <QDir>
#include <QFileDialog>
#include <QKeySequence>
#include <QMenu>
#include <QMessageBox>
#include <QTimer>

#include <nlohmann/json.hpp>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkType.h>

#include "vh/io/nrrd_writer.h"
#include "vh/runtime/session.h"
#include "vh/ui/view/scene_view.h"

namespace vh::ui {

namespace {
constexpr int kDrainPeriod_ms = 20;
constexpr std::size_t kDrainBatch = 1u << 16;

const char* nrrdType(int vtk_type) {
  switch (vtk_type) {
    case VTK_UNSIGNED_CHAR: return "uchar";
    case VTK_SHORT: return "short";
    case VTK_UNSIGNED_SHORT: return "ushort";
    case VTK_FLOAT: return "float";
    default: return nullptr;
  }
}
}  // namespace

std::vector<std::uint64_t> pictureIndices(const haptics::ScalarVolume& felt, const haptics::ScalarVolume& scan,
                                          std::span<const std::uint64_t> felt_indices) {
  const auto& fg = felt.geometry();
  const auto& sg = scan.geometry();
  if (fg.sameGridAs(sg)) return {felt_indices.begin(), felt_indices.end()};
  std::vector<std::uint64_t> out;
  out.reserve(felt_indices.size());
  for (const std::uint64_t index : felt_indices) {
    const std::array<int, 3> v = fg.voxelOf(index);
    const Eigen::Vector3d g = scan.gridCoordinates(fg.pointOf_W(Eigen::Vector3d(v[0], v[1], v[2])));
    const long a = std::lround(g.x()), b = std::lround(g.y()), c = std::lround(g.z());
    if (a < 0 || b < 0 || c < 0 || a >= sg.dims[0] || b >= sg.dims[1] || c >= sg.dims[2]) continue;
    out.push_back(sg.indexOf(a, b, c));
  }
  return out;
}

DrillController::DrillController(runtime::Session& session, SceneView& view, QObject* parent)
    : QObject(parent), session_(session), view_(view) {
  buffer_.resize(kDrainBatch);
  observer_ = session_.addObserver([this](runtime::SessionChange what) { onSessionChanged(what); });
  timer_ = new QTimer(this);
  timer_->setInterval(kDrainPeriod_ms);
  connect(timer_, &QTimer::timeout, this, &DrillController::drain);
  timer_->start();
}

DrillController::~DrillController() { session_.removeObserver(observer_); }

void DrillController::addMenuActions(QMenu* haptics_menu, QMenu* file_menu, QWidget* dialog_parent) {
  if (haptics_menu != nullptr) {
    action_ = haptics_menu->addAction("&Drill (Spin the Burr)", this, [this](bool on) { setDrilling(on); });
    action_->setCheckable(true);
    action_->setShortcut(QKeySequence("Ctrl+B"));
    action_->setToolTip("The tool's burr removes the bone it presses on: harder bone slower (hardness from HU or "
                        "the segments); critical segments raise an alert when cut");
  }
  if (file_menu != nullptr) {
    file_menu->addAction("Export &Drilled Volume...", this, [this, dialog_parent] {
      const QString path = QFileDialog::getSaveFileName(dialog_parent, "Export the drilled volume (NRRD) and the removed region (.seg.nrrd)",
                                                        QDir::home().filePath("drilled.nrrd"), "NRRD volumes (*.nrrd)");
      if (path.isEmpty()) return;
      try {
        exportDrilledWithNotice(path.toStdString());
      } catch (const std::exception& e) {
        QMessageBox::warning(dialog_parent, "Export Drilled Volume", e.what());
      }
    });
  }
}

std::filesystem::path DrillController::exportDrilledWithNotice(std::filesystem::path nrrd) {
  if (nrrd.extension() != ".nrrd") nrrd += ".nrrd";
  std::filesystem::path seg = nrrd;
  seg.replace_extension(".seg.nrrd");
  const QString name = QString::fromStdString(nrrd.string());
  emit message("Exporting the drilled volume to " + name + " ...", 0);
  QCoreApplication::processEvents(QEventLoop::ExcludeUserInputEvents);  // show it before the write
  try {
    exportDrilled(nrrd, seg);
  } catch (...) {
    emit message(QString(), 0);
    throw;
  }
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(nrrd, ec);
  emit message(QString("Drilled volume exported: %1 (%2 MB) and the removed region %3 (%4 mm3)")
                   .arg(name)
                   .arg(ec ? 0.0 : static_cast<double>(bytes) / 1e6, 0, 'f', 1)
                   .arg(QString::fromStdString(seg.filename().string()))
                   .arg(removed_mm3_, 0, 'f', 1),
               20000);
  return nrrd;
}

void DrillController::setDrilling(bool on) {
  try {
    session_.setDrilling(on);
    if (on && session_.drilling()) {
      if (view_.hasScene()) view_.actors().prepareRemoval();
      const auto& drill = session_.hapticThread() != nullptr ? session_.hapticThread()->drill() : nullptr;
      const double r_mm = drill != nullptr ? drill->burr().radius_m * 1e3 : 0.0;
      emit message(QString("Drill on: the %1 mm burr removes what it presses on (Ctrl+B stops it)").arg(r_mm, 0, 'f', 1), 5000);
    } else if (!on) {
      emit message("Drill off", 3000);
    } else {
      emit message("Drilling needs a scan and a tool", 4000);
    }
  } catch (const std::exception& e) {
    emit message(QString("Cannot drill: %1").arg(e.what()), 6000);
  }
  if (action_ != nullptr) {
    const QSignalBlocker block(action_);
    action_->setChecked(session_.drilling());
  }
}

void DrillController::onSessionChanged(runtime::SessionChange what) {
  if (action_ != nullptr) {
    const QSignalBlocker block(action_);
    action_->setChecked(session_.drilling());
    action_->setEnabled(session_.hasScene());
  }
  // A new scene starts undrilled (or from its recording's cavity: drain() shows it). Haptic
  // threads rebuilt for another reason keep the cavity: drain() meets their new drill and shows
  // the cavity it started from.
  if (runtime::has(what, runtime::SessionChange::kScene)) reset();
}

void DrillController::reset() {
  drill_seen_.reset();
  removed_ = 0;
  removed_mm3_ = 0.0;
  removed_mask_.clear();
  critical_seen_.clear();
  carved_.clear();
  if (view_.hasScene()) view_.actors().restoreVolume();
  emit cavityChanged();
}

void DrillController::drain() {
  runtime::HapticThread* thread = session_.hapticThread();
  if (thread == nullptr || thread->drill() == nullptr || !view_.hasScene() || !session_.hasScene()) return;
  runtime::Drill& drill = *thread->drill();
  const haptics::ScalarVolume& felt = drill.removal().volume();
  const haptics::ScalarVolume& scan = *session_.live().scan_field;
  if (view_.actors().shownImage() == nullptr) return;
  const double removed_value = view_.actors().removedValue();
  if (removed_mask_.empty()) removed_mask_.assign(scan.geometry().voxelCount(), 0);
  if (drill_seen_.get() != &drill) {  // a new drill: its log starts empty, its field from its cavity
    // The threads were rebuilt: what the old drill cut since the last drain is in the new one's
    // cavity (shown below); its critical removals are still told.
    if (drill_seen_ != nullptr) reportCritical(*drill_seen_, nullptr);
    drill_seen_ = thread->drill();
    critical_seen_.assign(drill.removal().materials().size(), 0);
    showCavity(drill.cavityAtStart().get(), removed_value);
    // The shadow's field: the felt field the new drill started from, with its cavity.
    const auto& start = drill.cavityAtStart();
    carved_.reset(session_.live().hapticField(),
                  start != nullptr ? runtime::cavityVoxelsOn(*start, felt.geometry()) : std::vector<std::uint64_t>{});
    emit cavityChanged();
  }
  const std::uint64_t carved_before = carved_.version();
  for (;;) {
    const std::size_t n = drill.removal().drainRemoved(buffer_);
    if (n == 0) break;
    image_indices_ = pictureIndices(felt, scan, std::span<const std::uint64_t>(buffer_.data(), n));
    for (const std::uint64_t index : image_indices_)
      if (index < removed_mask_.size()) removed_mask_[index] = 1;
    view_.actors().removeVoxels(image_indices_, removed_value);
    carved_.remove(std::span<const std::uint64_t>(buffer_.data(), n));
    removed_ += n;
    removed_mm3_ += static_cast<double>(n) * drill.removal().voxelVolume_mm3();
    view_.noteMotion();  // a growing cavity is motion: interactive frames until it settles
    view_.requestRender();
  }
  if (carved_.version() != carved_before) emit cavityChanged();
  reportCritical(drill, thread);
}

void DrillController::reportCritical(const runtime::Drill& drill, runtime::HapticThread* thread) {
  // Critical segments: every removal is an alert and an event in the recording.
  const auto& materials = drill.removal().materials();
  for (std::size_t m = 0; m < materials.size() && m < critical_seen_.size(); ++m) {
    if (!materials[m].critical) continue;
    const std::uint64_t now = drill.removal().removedVoxels(static_cast<int>(m));
    if (now <= critical_seen_[m]) continue;
    const std::uint64_t delta = now - critical_seen_[m];
    critical_seen_[m] = now;
    const double mm3 = static_cast<double>(delta) * drill.removal().voxelVolume_mm3();
    nlohmann::json detail{{"segment", materials[m].name}, {"voxels", delta}, {"mm3", mm3}};
    if (thread != nullptr) thread->recordEvent("critical_removed", detail.dump());
    emit message(QString("CRITICAL: the burr removed %1 voxels (%2 mm3) of %3")
                     .arg(delta)
                     .arg(mm3, 0, 'f', 2)
                     .arg(QString::fromStdString(materials[m].name)),
                 8000);
  }
}

void DrillController::showCavity(const runtime::DrilledCavity* cavity, double removed_value) {
  const haptics::ScalarVolume& scan = *session_.live().scan_field;
  const std::vector<std::uint64_t> shown =
      cavity != nullptr ? runtime::cavityVoxelsOn(*cavity, scan.geometry()) : std::vector<std::uint64_t>{};
  std::vector<std::uint8_t> target(removed_mask_.size(), 0);
  for (const std::uint64_t index : shown)
    if (index < target.size()) target[index] = 1;
  bool only_more = true;  // the picture shows nothing the cavity lacks
  for (std::size_t i = 0; i < target.size() && only_more; ++i) only_more = removed_mask_[i] <= target[i];
  std::vector<std::uint64_t> missing;
  if (only_more) {
    for (const std::uint64_t index : shown)
      if (index < removed_mask_.size() && removed_mask_[index] == 0) missing.push_back(index);
  } else {  // the cavity shrank (moved onto a coarser felt field): from the scan again
    view_.actors().restoreVolume();
    missing = shown;
  }
  removed_mask_ = std::move(target);
  if (!missing.empty()) {
    view_.actors().removeVoxels(missing, removed_value);
    view_.requestRender();
  }
  removed_ = cavity != nullptr ? cavity->voxels.size() : 0;
  removed_mm3_ = cavity != nullptr ? static_cast<double>(removed_) * cavity->grid.spacing_m.prod() * 1e9 : 0.0;
}

void DrillController::exportDrilled(const std::filesystem::path& nrrd_path, const std::filesystem::path& seg_path) const {
  if (!view_.hasScene() || removed_ == 0 || !session_.hasScene())
    throw std::runtime_error(nrrd_path.string() + ": nothing was drilled yet (Haptics > Drill, then press on bone)");
  vtkImageData* image = view_.actors().shownImage();
  const haptics::ScalarVolume& scan = *session_.live().scan_field;
  const auto& g = scan.geometry();
  vtkDataArray* scalars = image->GetPointData()->GetScalars();
  const char* type = scalars != nullptr ? nrrdType(scalars->GetDataType()) : nullptr;
  if (type == nullptr || scalars->GetNumberOfTuples() != static_cast<vtkIdType>(g.voxelCount()))
    throw std::runtime_error(nrrd_path.string() + ": the scan's voxel type cannot be written as NRRD");
  io::NrrdVolume volume;
  volume.dims = g.dims;
  volume.spacing_m = g.spacing_m;
  volume.origin_W_m = g.origin_W_m;
  volume.direction_W = g.direction_W;
  volume.type = type;
  volume.voxels = scalars->GetVoidPointer(0);
  io::writeNrrd(nrrd_path, volume);
  // The removed region as 3D Slicer's segmentation: one binary layer, label 1, "drilled".
  io::NrrdVolume seg = volume;
  seg.type = "uchar";
  seg.voxels = removed_mask_.data();
  seg.key_values = {{"Segment0_ID", "drilled"},
                    {"Segment0_Name", "drilled"},
                    {"Segment0_Color", "0.9 0.3 0.2"},
                    {"Segment0_LabelValue", "1"},
                    {"Segment0_Layer", "0"},
                    {"Segment0_Extent", "0 " + std::to_string(g.dims[0] - 1) + " 0 " + std::to_string(g.dims[1] - 1) +
                                            " 0 " + std::to_string(g.dims[2] - 1)},
                    {"Segmentation_MasterRepresentation", "Binary labelmap"},
                    {"Segmentation_ContainedRepresentationNames", "Binary labelmap|"},
                    {"Segmentation_ReferenceImageExtentOffset", "0 0 0"}};
  io::writeNrrd(seg_path, seg);
}

}  // namespace vh::ui
