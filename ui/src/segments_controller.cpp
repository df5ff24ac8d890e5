// Segments in the main window (see segments_controller.h).
#include "vh/ui/segments_controller.h"

#include <algorithm>
#include <functional>
#include <map>
#include <memory>

#include <sys/resource.h>
#include <unistd.h>

#include <QApplication>
#include <QDockWidget>
#include <QEventLoop>
#include <QFileDialog>
#include <QMainWindow>
#include <QPointF>
#include <QStatusBar>
#include <QStringList>
#include <QThread>
#include <vtkMatrix4x4.h>
#include <vtkPolyData.h>

#include "vh/io/segmentation.h"
#include "vh/ui/devices/device_input.h"
#include "vh/ui/panels/segments_panel.h"
#include "vh/ui/preferences.h"
#include "vh/ui/view/scene_view.h"
#include "vh/ui/view/segment_surfaces.h"
#include "vh/ui/view/vtk_view.h"

namespace vh::ui {
namespace {

QString q(const std::string& s) { return QString::fromStdString(s); }

/// A wait cursor while a segmentation is read or its felt field smoothed (seconds on a CT).
struct WaitCursor {
  WaitCursor() { QApplication::setOverrideCursor(Qt::WaitCursor); }
  ~WaitCursor() { QApplication::restoreOverrideCursor(); }
};

std::vector<std::string> segmentNames(const io::LoadedSegmentation& seg, const std::vector<int>& indices) {
  std::vector<std::string> out;
  for (const int s : indices) out.push_back(seg.segments.at(static_cast<std::size_t>(s)).name);
  return out;
}

}  // namespace

SegmentsController::SegmentsController(runtime::Session& session, SceneView& view, QMainWindow* window,
                                       QStatusBar* status_bar, Preferences& prefs, DeviceInput* device_input)
    : QObject(window),
      session_(session),
      view_(view),
      prefs_(prefs),
      device_input_(device_input),
      window_(window),
      status_bar_(status_bar) {
  panel_ = new SegmentsPanel(window);
  dock_ = new QDockWidget("Segments", window);
  dock_->setObjectName("segmentsDock");
  dock_->setWidget(panel_);
  window->addDockWidget(Qt::RightDockWidgetArea, dock_);
  connect(panel_, &SegmentsPanel::choicesChanged, this, [this](const SegmentChoices& c) { apply(c); });
  connect(panel_, &SegmentsPanel::hardnessChanged, this, [this](int segment, double J_per_mm3) {
    const runtime::SegmentSet* set = session_.hasScene() ? session_.live().segments.get() : nullptr;
    if (set == nullptr || segment < 0 || static_cast<std::size_t>(segment) >= set->size()) return;
    try {
      session_.setHardness(set->name(segment), J_per_mm3);
    } catch (const std::exception& e) {
      emit errorReported("Segments", q(e.what()));
    }
  });
  connect(panel_, &SegmentsPanel::goToSegmentRequested, this, &SegmentsController::goToSegment);
  connect(panel_, &SegmentsPanel::openRequested, this, [this] { openDialog(prefs_.last_folder); });
  panel_->setThroughScan(prefs_.segments_through_scan);
  view_.setSegmentsThroughScan(prefs_.segments_through_scan);
  connect(panel_, &SegmentsPanel::throughScanToggled, this, &SegmentsController::setThroughScan);
  panel_->setSounds(prefs_.burr_sound, prefs_.alert_sound);
  connect(panel_, &SegmentsPanel::burrSoundToggled, this, [this](bool on) { prefs_.burr_sound = on; });
  connect(panel_, &SegmentsPanel::alertSoundToggled, this, [this](bool on) { prefs_.alert_sound = on; });
  connect(panel_->smoothingBox(), &RangeSpinBox::outOfRange, this,
          [this](const QString& message) { status_bar_->showMessage(message, 8000); });
  observer_ = session_.addObserver([this](runtime::SessionChange what) { onSessionChanged(what); });
}

SegmentsController::~SegmentsController() { session_.removeObserver(observer_); }

void SegmentsController::onSessionChanged(runtime::SessionChange what) {
  if (runtime::has(what, runtime::SessionChange::kDrill) && session_.hasScene()) panel_->showHardness(session_.hardness());
  if (!runtime::has(what, runtime::SessionChange::kScene) && !runtime::has(what, runtime::SessionChange::kSegments)) {
    return;
  }
  const runtime::SegmentSet* set = session_.hasScene() ? session_.live().segments.get() : nullptr;
  panel_->showSegments(set);
  if (session_.hasScene()) panel_->showHardness(session_.hardness());
  names_->set(set);
  if (session_.hasScene()) {
    // A segment whose file colour the scan surface would hide is drawn in another: say which.
    const std::vector<int> recoloured = view_.setSegments(set);
    QStringList said;
    for (const int s : recoloured) {
      const std::vector<double> c = view_.segmentSurfaces()->colour(s);
      if (c.size() == 3) panel_->setDisplayColour(s, {c[0], c[1], c[2]});
      said << q(set->name(s));
    }
    if (!said.isEmpty())
      status_bar_->showMessage(QString("Segment %1: its colour is too close to the scan surface's; drawn in a distinct "
                                       "colour (the swatch in the Segments panel)")
                                   .arg(said.join(", ")),
                               12000);
  }
  // A scene that comes with segments shows them in front (where to choose what is felt).
  if (set != nullptr && runtime::has(what, runtime::SessionChange::kScene)) dock_->raise();
  touched_ = -1;
  critical_alerts_ = 0;
  panel_->setTouched(-1);
  view_.setTouchedSegment(-1, {});
}

namespace {

/// What a segmentation's open computes off the GUI thread.
struct PreparedSegments {
  std::shared_ptr<const runtime::SegmentSet> set;
  runtime::SegmentationSpec spec;
  std::map<int, SegmentSurface> surfaces;
  std::string error;  // empty: prepared
};

/// The calling thread at a lower CPU priority (nice 10; raising it needs no privilege), so that
/// a load leaves the cores to the haptic threads when they run at normal priority, and to the
/// window's drawing.
void lowerThisThreadsPriority() noexcept { (void)setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10); }

/// Runs `work` (seconds on a CT: reading, smoothing, contouring; it must not touch a widget) on
/// a worker thread at lower priority while the window's event loop goes on drawing, with user
/// input held until it is done (nothing else changes the scene meanwhile from the window), and
/// `message` in the status bar. @return the error `work` threw, empty when it finished.
std::string runBesideTheWindow(QStatusBar* bar, const QString& message, const std::function<void()>& work) {
  WaitCursor wait;
  bar->showMessage(message);
  std::string error;
  std::unique_ptr<QThread> worker(QThread::create([&] {
    lowerThisThreadsPriority();
    try {
      work();
    } catch (const std::exception& e) {
      error = e.what();
      if (error.empty()) error = "failed";
    } catch (...) {
      error = "failed";
    }
  }));
  QEventLoop loop;
  QObject::connect(worker.get(), &QThread::finished, &loop, &QEventLoop::quit);
  worker->start();
  if (!worker->isFinished()) loop.exec(QEventLoop::ExcludeUserInputEvents);
  worker->wait();
  bar->clearMessage();
  return error;
}

}  // namespace

bool SegmentsController::open(const std::filesystem::path& path) {
  if (!session_.hasScene()) {
    emit errorReported(q(path.string()), q(path.string()) + ": open a scan first; a segmentation is opened on it");
    return false;
  }
  // Reading the file, building the set and its surfaces takes seconds on a CT: a worker thread
  // at lower priority does it while the window goes on drawing (input held until it is done, so
  // nothing else changes the scene meanwhile); the haptic threads never wait for it.
  const io::LoadedVolume scan = session_.loaded().volume;  // a copy (shared voxels): the worker's, whatever opens meanwhile
  PreparedSegments prepared;
  prepared.error =
      runBesideTheWindow(status_bar_, QString("Opening segmentation %1...").arg(q(path.filename().string())), [&] {
        // On the scan shown: a DICOM SEG is placed on its grid and checked against its series.
        io::LoadedSegmentation seg = io::loadSegmentation(path, scan);
        prepared.spec.path = std::filesystem::absolute(path).lexically_normal().string();
        prepared.set = runtime::SegmentSet::fromSpec(std::move(seg), prepared.spec, path.filename().string());  // all shown
        for (const int s : prepared.set->shown()) {
          if (prepared.set->segment(s).voxel_count > 0) prepared.surfaces[s] = buildSegmentSurface(*prepared.set, s);
        }
      });
  if (prepared.error.empty() && (!session_.hasScene() || session_.loaded().volume.field != scan.field))
    prepared.error = "another scan was opened while the segmentation loaded; open it again on this one";
  if (!prepared.error.empty()) {
    emit errorReported(q(path.string()), q(prepared.error));
    return false;
  }
  try {
    view_.adoptSegmentSurfaces(*prepared.set, std::move(prepared.surfaces));
    session_.setSegments(std::move(prepared.set), prepared.spec);
  } catch (const std::exception& e) {
    emit errorReported(q(path.string()), q(e.what()));
    return false;
  }
  dock_->show();
  dock_->raise();
  status_bar_->showMessage(QString("Segments of %1: tick Felt to feel a segment, Critical to be warned when it is touched")
                               .arg(q(path.filename().string())),
                           8000);
  return true;
}

void SegmentsController::openDialog(const QString& folder) {
  const QString path = QFileDialog::getOpenFileName(window_, "Open a segmentation (3D Slicer .seg.nrrd, DICOM SEG, RT Structure Set or label map)",
                                                    folder, q(io::segmentationFileDialogFilter()));
  if (!path.isEmpty()) open(path.toStdString());
}

bool SegmentsController::apply(const SegmentChoices& choices) {
  if (!session_.hasScene() || session_.live().segments == nullptr) return false;
  const runtime::SegmentSet& current = *session_.live().segments;
  runtime::SegmentationSpec spec = session_.live().segmentation.value_or(runtime::SegmentationSpec{});
  const io::LoadedSegmentation& seg = current.segmentation();
  spec.felt = segmentNames(seg, choices.felt);
  spec.shown = segmentNames(seg, choices.shown);
  spec.critical = segmentNames(seg, choices.critical);
  spec.smoothing_voxels = choices.smoothing_voxels;
  // The distances as the table has them; those other than the scene's default are the spec's own.
  spec.proximity.per_segment.clear();
  for (std::size_t s = 0; s < choices.thresholds.size() && s < seg.segments.size(); ++s) {
    const runtime::ProximityThresholds& t = choices.thresholds[s];
    const bool critical = std::find(choices.critical.begin(), choices.critical.end(), static_cast<int>(s)) !=
                          choices.critical.end();  // the file takes distances of critical segments only
    if (critical && (t.warn_m != spec.proximity.defaults.warn_m || t.alarm_m != spec.proximity.defaults.alarm_m))
      spec.proximity.per_segment[seg.segments[s].name] = t;
  }
  // A felt choice smooths the segments' field (seconds on a CT): beside the window, as an open.
  const std::shared_ptr<const runtime::SegmentSet> kept = session_.live().segments;  // alive while the worker reads it
  std::shared_ptr<const runtime::SegmentSet> set;
  std::string error = runBesideTheWindow(status_bar_, "Building the felt segments' surface...", [&] {
    set = std::make_shared<const runtime::SegmentSet>(seg, choices.felt, choices.shown, choices.critical,
                                                      choices.smoothing_voxels, choices.thresholds);
  });
  if (error.empty() && (!session_.hasScene() || session_.live().segments != kept))
    error = "the segments changed while the choice was being applied; tick it again";
  if (!error.empty()) {
    emit errorReported("Segments", q(error));
    return false;
  }
  const bool felt_before = !kept->felt().empty();
  try {
    session_.setSegments(std::move(set), spec);
  } catch (const std::exception& e) {
    emit errorReported("Segments", q(e.what()));
    return false;
  }
  // Segments felt from now on lie inside the scan's surface as often as not (a tumour under the
  // skin): drawn through the scan, with the tool, the hand's surface is seen where the hand is.
  // Once, as Felt is first ticked; unticking the box again is kept.
  if (!felt_before && !choices.felt.empty() && !prefs_.segments_through_scan) {
    setThroughScan(true);
    status_bar_->showMessage("The felt segments and the tool are drawn through the scan (untick Through the scan in "
                             "the Segments panel to see them behind its surface)",
                             10000);
  }
  return true;
}

void SegmentsController::setThroughScan(bool on) {
  prefs_.segments_through_scan = on;
  panel_->setThroughScan(on);
  view_.setSegmentsThroughScan(on);
}

SegmentsController::GoTo SegmentsController::goToSegment(int segment) {
  if (!view_.frameSegment(segment)) {
    status_bar_->showMessage("That segment is not shown: tick Shown to draw it, then double-click it", 5000);
    return GoTo::kNotShown;
  }
  const runtime::SegmentSet* set = session_.hasScene() ? session_.live().segments.get() : nullptr;
  const QString name = set != nullptr && static_cast<std::size_t>(segment) < set->size() ? q(set->name(segment)) : "the segment";
  if (device_input_ == nullptr || session_.simulatedDevice() == nullptr || !session_.hapticsRunning()) {
    status_bar_->showMessage(QString("Framed %1; the tool stays where it is: it is put on the segment only with the "
                                     "simulated device and the haptics running")
                                 .arg(name),
                             6000);
    return GoTo::kFramedOnly;
  }
  // The segment's centre is the framed view's centre: touch the surface there, as a Ctrl+Shift+click.
  const VtkView* widget = view_.widget();
  if (!device_input_->touchSurfaceAt(QPointF(0.5 * widget->width(), 0.5 * widget->height()), DeviceInput::kTouchDepth_m)) {
    status_bar_->showMessage(
        QString("Framed %1; no felt surface along the line of sight through its centre: the tool stays where it is")
            .arg(name),
        6000);
    return GoTo::kNoSurface;
  }
  status_bar_->showMessage(
      QString("Framed %1; the tool rests on the first felt surface along the line of sight through its centre").arg(name),
      6000);
  return GoTo::kPlaced;
}

void SegmentsController::showSnapshot(const runtime::HapticSnapshot& snapshot) {
  const int segment = snapshot.contacts > 0 ? snapshot.segment : -1;
  if (segment == touched_) return;
  touched_ = segment;
  panel_->setTouched(segment);
  const runtime::SegmentSet* set = session_.live().segments.get();
  const bool critical = set != nullptr && segment >= 0 && set->isCritical(segment);
  std::string alert;
  if (critical) {
    alert = "CRITICAL: " + set->name(segment) + " touched";
    ++critical_alerts_;
    status_bar_->showMessage(q(alert), 4000);
    if (panel_->alertSound()) emit alertSoundRequested();
  }
  view_.setTouchedSegment(segment, alert);
}

}  // namespace vh::ui
