#pragma once
/// @file
/// The isovalue bar above the view: a label with the data's unit, the slider with the volume's
/// histogram behind it, and a spin box in the data's units. It observes runtime::Session (the
/// one owner of the isovalue) and sends it setIsovalue(); it keeps no isovalue of its own.
/// GUI thread only.

#include <QWidget>

#include <string>

#include "vh/io/volume_loader.h"
#include "vh/runtime/session.h"
#include "vh/ui/panels/histogram.h"

class QDoubleSpinBox;
class QLabel;

namespace vh::ui {

class HistogramSlider;

/// The unit the isovalue bar puts on a volume's values.
struct ValueUnit {
  std::string symbol;   ///< Short, on the label: "HU", "SUVbw", "Bq/ml", "a.u.".
  std::string meaning;  ///< One sentence for the tooltip: what the values are.
};

/// The unit of `info`'s values, for every modality: the loader's unit when it names one (CT:
/// "HU"; PET: "SUVbw" or "Bq/ml" as loaded), else arbitrary units, "a.u." (MR intensities
/// have no physical scale: they are the scanner's; a PET without Units or a file without a
/// modality say that the file names no unit).
ValueUnit valueUnitOf(const io::VolumeInfo& info);

class IsovalueBar : public QWidget {
  Q_OBJECT

 public:
  /// Observes `session`, which must outlive the bar.
  IsovalueBar(runtime::Session& session, QWidget* parent = nullptr);
  ~IsovalueBar() override;

  /// The histogram of the new scene's volume (data units), its unit ("HU": CT tissue labels).
  /// The label's unit comes from the session's scene (valueUnitOf()), shown on every scene.
  void setHistogram(const Histogram& histogram, const std::string& unit);
  /// The label before the slider, "Isovalue [HU]" ("Isovalue" without a scene).
  QLabel* label() const noexcept { return label_; }
  /// One spin-box step up (+1) or down (-1) (the [ and ] keys).
  void step(int direction);
  /// The slider position <-> data value mapping over the session's value range.
  double sliderToValue(int position) const;
  int valueToSlider(double value) const;

  HistogramSlider* slider() const noexcept { return slider_; }
  QDoubleSpinBox* spinBox() const noexcept { return spin_; }

 signals:
  /// The slider's handle was pressed / released (interactive frames meanwhile).
  void dragStarted();
  void dragEnded();
  /// Why an isovalue was not taken (soft tissue that cannot be built on the new surface).
  void message(const QString& text, int timeout_ms);

 private:
  /// session_.setIsovalue(), an error said (message()) and the old value shown again.
  void apply(double value);
  void showSession(runtime::SessionChange what);

  runtime::Session& session_;
  int observer_ = 0;
  QLabel* label_ = nullptr;
  HistogramSlider* slider_ = nullptr;
  QDoubleSpinBox* spin_ = nullptr;
};

}  // namespace vh::ui
