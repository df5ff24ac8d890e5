#include "vh/ui/tissue_controller.h"

#include <algorithm>
#include <cmath>
#include <span>

#include <QCheckBox>
#include <QDockWidget>
#include <QHeaderView>
#include <QLabel>
#include <QMainWindow>
#include <QTableWidget>
#include <QTimer>
#include <QVBoxLayout>

#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/session.h"
#include "vh/runtime/tissue_scene.h"
#include "vh/tissue/material.h"
#include "vh/ui/view/scene_actors.h"
#include "vh/ui/view/scene_view.h"

namespace vh::ui {

namespace {
constexpr int kDrainPeriod_ms = 20;
}  // namespace

TissueController::TissueController(runtime::Session& session, SceneView& view, QMainWindow* window)
    : QObject(window), session_(session), view_(view) {
  auto* panel = new QWidget(window);
  auto* layout = new QVBoxLayout(panel);
  summary_ = new QLabel(panel);
  summary_->setWordWrap(true);
  summary_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  layout->addWidget(summary_);
  bands_ = new QTableWidget(0, 4, panel);
  bands_->setHorizontalHeaderLabels({"Where", "Material", "E [kPa]", "Poisson"});
  bands_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  bands_->horizontalHeader()->setStretchLastSection(true);
  bands_->verticalHeader()->setVisible(false);
  bands_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  bands_->setToolTip("What yields: segments of the scan's segmentation (taken first), then bands of the scan's "
                     "values, each with its material (hover a material for the measurement its figures come "
                     "from). Set in the scene file's \"tissue\" section.");
  layout->addWidget(bands_, 1);
  live_ = new QLabel(panel);
  live_->setWordWrap(true);
  live_->setToolTip("Indentation: how far the surface gave where the tool pushes, along its normal. Pushed: the "
                    "force on the tissue (equal and opposite to what the hand feels at rest). Held back: the "
                    "tissue springs back only as fast as the proxy leaves room, so no point of the tool is ever "
                    "inside the surface.");
  layout->addWidget(live_);
  show_ = new QCheckBox("Show the deformation", panel);
  show_->setChecked(true);
  show_->setToolTip("The picture shows the tissue as the hand feels it, frame by frame; off: the scan at rest");
  connect(show_, &QCheckBox::toggled, this, [this](bool on) {
    if (!view_.hasScene()) return;
    const tissue::DeformedWindow rest;
    const tissue::DeformedWindow& w = on ? window_ : rest;
    if (view_.actors().showVoxelBox(w.lo, w.hi, std::span<const float>(w.values_F))) view_.requestRender();
  });
  layout->addWidget(show_);
  dock_ = new QDockWidget("Tissue", window);
  dock_->setObjectName("tissueDock");
  dock_->setWidget(panel);
  window->addDockWidget(Qt::RightDockWidgetArea, dock_);
  dock_->hide();

  timer_ = new QTimer(this);
  timer_->setInterval(kDrainPeriod_ms);
  connect(timer_, &QTimer::timeout, this, &TissueController::drain);
  observer_ = session_.addObserver([this](runtime::SessionChange what) { onSessionChanged(what); });
  describeScene();
}

TissueController::~TissueController() { session_.removeObserver(observer_); }

bool TissueController::showingDeformation() const noexcept { return show_->isChecked(); }

void TissueController::onSessionChanged(runtime::SessionChange what) {
  if (runtime::has(what, runtime::SessionChange::kScene)) {
    backToRest();
    scene_seen_ = nullptr;
    windows_shown_ = 0;
    told_mismatch_ = false;
    deepest_m_ = 0.0;
    describeScene();
  } else if (runtime::has(what, runtime::SessionChange::kIsovalue)) {
    describeScene();
  }
}

void TissueController::describeScene() {
  const bool has = session_.hasScene() && session_.live().tissue.has_value();
  // Only a scene with tissue runs the drain: a rigid scene starts nothing of this.
  if (has) {
    timer_->start();
  } else {
    timer_->stop();
  }
  dock_->setVisible(has);
  if (has) dock_->raise();
  bands_->setRowCount(0);
  if (!has) {
    summary_->setText("This scene has no soft tissue: everything the hand touches is rigid.");
    live_->clear();
    return;
  }
  const runtime::TissueSpec& spec = *session_.live().tissue;
  const auto addRow = [this](const QString& where, const std::string& material) {
    const int row = bands_->rowCount();
    bands_->insertRow(row);
    bands_->setItem(row, 0, new QTableWidgetItem(where));
    auto* name = new QTableWidgetItem(QString::fromStdString(material));
    try {
      const tissue::Material m = tissue::materialPreset(material);
      name->setToolTip(QString::fromStdString(m.source));
      bands_->setItem(row, 2, new QTableWidgetItem(QString::number(m.youngs_modulus_Pa / 1e3, 'g', 4)));
      bands_->setItem(row, 3, new QTableWidgetItem(QString::number(m.poisson_ratio, 'g', 3)));
    } catch (const std::exception& e) {
      name->setToolTip(e.what());
    }
    bands_->setItem(row, 1, name);
  };
  for (const runtime::TissueSegment& segment : spec.segments)
    addRow(QString("segment %1").arg(QString::fromStdString(segment.segment)), segment.material);
  for (const runtime::TissueBand& band : spec.bands)
    addRow(QString("values %1 to %2").arg(band.min, 0, 'g', 6).arg(band.max, 0, 'g', 6), band.material);
  const runtime::HapticThread* thread = session_.hapticThread();
  const tissue::DeformableScene* scene = thread != nullptr ? thread->tissue().get() : nullptr;
  QString lattice = QString("a lattice of %1 mm cells").arg(spec.cell_size_m * 1e3, 0, 'g', 3);
  if (scene != nullptr)
    lattice += QString(", %1 nodes, %2 of them under the surface the tool can reach")
                   .arg(scene->region().model.lattice().nodeCount())
                   .arg(scene->compliance().nodeCount());
  summary_->setText(QString("The tissue yields under the tool (finite elements on %1); anything above %2 stays "
                            "rigid. Felt at the isovalue %3: the region and its compliance belong to that surface, "
                            "so changing the isovalue rebuilds them.")
                        .arg(lattice)
                        .arg(spec.rigid_above ? QString::number(*spec.rigid_above, 'g', 6) : QString("the bands"))
                        .arg(session_.live().isovalue, 0, 'g', 6));
  showFigures();
}

void TissueController::showFigures() {
  if (!session_.live().tissue) return;
  if (window_.empty()) {
    live_->setText(QString("At rest. Deepest indentation this scene: %1 mm.").arg(deepest_m_ * 1e3, 0, 'f', 2));
    return;
  }
  QString text = QString("Indentation %1 mm, tissue pushed %2 N")
                     .arg(window_.indentation_m * 1e3, 0, 'f', 2)
                     .arg(window_.push_N, 0, 'f', 3);
  if (window_.felt_fraction < 1.0)
    text += QString(", spring-back held back by the tool (%1 %)").arg(100.0 * window_.felt_fraction, 0, 'f', 0);
  text += QString(". Deepest this scene: %1 mm.").arg(deepest_m_ * 1e3, 0, 'f', 2);
  live_->setText(text);
}

void TissueController::backToRest() {
  const bool had = !window_.empty();
  window_ = tissue::DeformedWindow{};
  if (had && view_.hasScene()) {
    (void)view_.actors().showVoxelBox(window_.lo, window_.hi, {});
    view_.requestRender();
  }
}

void TissueController::drain() {
  runtime::HapticThread* thread = session_.hapticThread();
  tissue::DeformableScene* scene = thread != nullptr ? thread->tissue().get() : nullptr;
  if (scene == nullptr || !view_.hasScene()) return;
  if (scene != scene_seen_) {  // new haptic threads: their tissue starts at rest
    backToRest();
    scene_seen_ = scene;
    describeScene();
  }
  if (!scene->takeDeformedWindow(window_)) return;
  deepest_m_ = std::max(deepest_m_, window_.indentation_m);
  showFigures();
  if (!show_->isChecked()) return;
  if (view_.actors().showVoxelBox(window_.lo, window_.hi, std::span<const float>(window_.values_F))) {
    ++windows_shown_;
    view_.noteMotion();  // a moving surface is motion: interactive frames until it settles
    view_.requestRender();
  } else if (!told_mismatch_) {
    emit message("The picture shows the tissue at rest: the felt field's grid differs from the image's", 8000);
    told_mismatch_ = true;
  }
}

}  // namespace vh::ui
