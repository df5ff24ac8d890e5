#include "vh/ui/panels/load_notices.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <iostream>
#include <string_view>

#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QScrollArea>
#include <QSignalBlocker>
#include <QToolButton>
#include <QVBoxLayout>

namespace vh::ui {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

int noticeRank(const std::string& notice) {
  // Key phrases of io's notices, most important first; what the values mean (a PET's SUV or
  // its absence) right after what moved voxels.
  static constexpr std::array<std::string_view, 10> kOrder = {"gantry tilt", "sheared",    "missing slice", "suv",
                                                              "spacing",     "resampled",  "duplicate",     "skipped",
                                                              "time point",  "series"};
  const std::string text = lower(notice);
  // The scene's note on its own tool (runtime::feltGapNotice(): "tool: at 1.50 mm point spacing
  // ...") after every note on the scan: a choice in the Haptics panel, not how the scan was read.
  if (text.starts_with("tool:")) return static_cast<int>(kOrder.size()) + 1;
  for (std::size_t i = 0; i < kOrder.size(); ++i) {
    if (text.find(kOrder[i]) != std::string::npos) return static_cast<int>(i);
  }
  return static_cast<int>(kOrder.size());
}

std::string primaryNotice(const std::vector<std::string>& notices) {
  const auto best = std::min_element(notices.begin(), notices.end(), [](const std::string& a, const std::string& b) {
    return noticeRank(a) < noticeRank(b);
  });
  return best == notices.end() ? std::string() : *best;
}

QString statusNote(const std::vector<std::string>& notices) {
  const std::string first = primaryNotice(notices);
  if (first.empty()) return {};
  const QString count = notices.size() == 1 ? QString("1 load note") : QString("%1 load notes").arg(notices.size());
  return count + " (Help > Load Notes): " + QString::fromStdString(first);
}

LoadNoticePanel::LoadNoticePanel(QWidget* parent)
    : QFrame(parent),
      summary_(new QLabel(this)),
      details_(new QToolButton(this)),
      details_area_(new QScrollArea(this)),
      text_(new QLabel),
      close_(new QToolButton(this)),
      phase_row_(new QWidget(this)),
      phase_label_(new QLabel(phase_row_)),
      phase_spin_(new RangeIntSpinBox("the time point", phase_row_)),
      phase_load_(new QPushButton("Load This Time Point", phase_row_)) {
  setObjectName("loadNoticePanel");
  setFrameShape(QFrame::StyledPanel);
  // Amber, as a notice that is not an error; dark text whatever the palette.
  setStyleSheet(
      "#loadNoticePanel { background: #fff4ce; border: 1px solid #d9a400; border-radius: 3px; }"
      "#loadNoticePanel QLabel { color: #3a2e00; }");
  summary_->setObjectName("loadNoticeSummary");
  summary_->setTextFormat(Qt::RichText);
  summary_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  summary_->setMinimumWidth(1);  // elided by the layout, never widening the window
  details_->setObjectName("loadNoticeDetails");
  details_->setCheckable(true);
  details_->setAutoRaise(true);
  text_->setObjectName("loadNoticeText");
  text_->setWordWrap(true);
  text_->setTextFormat(Qt::RichText);
  text_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  text_->setStyleSheet("background: transparent;");
  details_area_->setObjectName("loadNoticeDetailsArea");
  details_area_->setWidget(text_);
  details_area_->setWidgetResizable(true);
  details_area_->setFrameShape(QFrame::NoFrame);
  details_area_->setStyleSheet("QScrollArea, QScrollArea > QWidget > QWidget { background: transparent; }");
  details_area_->setMaximumHeight(kMaxDetailLines * fontMetrics().lineSpacing() + 8);
  details_area_->hide();
  close_->setObjectName("loadNoticeClose");
  close_->setText(QString::fromUtf8("\u2715"));
  close_->setAutoRaise(true);
  close_->setToolTip("Hide these notes (Help > Load Notes shows them again)");
  phase_spin_->setObjectName("loadNoticePhase");
  phase_spin_->setToolTip("Time point (cardiac phase, dynamic frame or echo) of the 4-D series, from 1");
  phase_load_->setObjectName("loadNoticeLoadPhase");

  auto* phase_layout = new QHBoxLayout(phase_row_);
  phase_layout->setContentsMargins(0, 0, 0, 0);
  phase_layout->addWidget(new QLabel("Time point", phase_row_));
  phase_layout->addWidget(phase_spin_);
  phase_layout->addWidget(phase_label_);
  phase_layout->addWidget(phase_load_);
  phase_layout->addStretch(1);

  auto* summary_row = new QHBoxLayout();
  summary_row->addWidget(summary_, 1);
  summary_row->addWidget(details_, 0, Qt::AlignTop);
  auto* column = new QVBoxLayout();
  column->setSpacing(2);
  column->addLayout(summary_row);
  column->addWidget(details_area_);
  column->addWidget(phase_row_);
  auto* layout = new QHBoxLayout(this);
  layout->setContentsMargins(8, 2, 4, 2);
  layout->addLayout(column, 1);
  layout->addWidget(close_, 0, Qt::AlignTop);

  connect(close_, &QToolButton::clicked, this, &QWidget::hide);
  connect(details_, &QToolButton::toggled, this, &LoadNoticePanel::setDetailsShown);
  connect(phase_load_, &QPushButton::clicked, this, unlessRefused(*this, {phase_spin_}, [this] {
    runtime::SceneSpec spec = spec_;
    spec.volume.phase = phase_spin_->value() - 1;
    emit reloadRequested(spec, opened_);
  }));
  hide();
}

void LoadNoticePanel::setLoaded(const QString& title, const runtime::SceneSpec& spec, const io::VolumeInfo& info,
                                const std::filesystem::path& opened) {
  for (const std::string& n : info.notices) std::cerr << "volume-haptics: note: " << n << '\n';
  title_ = title;
  spec_ = spec;
  opened_ = opened;
  phase_count_ = std::max(1, info.phase_count);
  notices_.clear();
  for (const std::string& n : info.notices) notices_ << QString::fromStdString(n);
  phase_spin_->setRange(1, phase_count_);
  phase_spin_->setValue(std::clamp(info.phase + 1, 1, phase_count_));
  phase_label_->setText(QString("of %1").arg(phase_count_));
  details_->setChecked(false);  // a new scan: the summary line only
  refresh();
  setVisible(!notices_.isEmpty() || phase_count_ > 1);
}

void LoadNoticePanel::reopen() {
  refresh();
  setDetailsShown(true);
  show();
}

void LoadNoticePanel::setDetailsShown(bool shown) {
  const bool any = notices_.size() > 1;
  details_area_->setVisible(shown && any);
  const QSignalBlocker block(details_);
  details_->setChecked(shown && any);
  details_->setText(shown ? "Less" : QString("All %1").arg(notices_.size()));
}

bool LoadNoticePanel::detailsShown() const { return details_area_->isVisibleTo(this); }

void LoadNoticePanel::refresh() {
  const QString name = title_.isEmpty() ? QString("the volume") : title_.toHtmlEscaped();
  if (notices_.isEmpty()) {
    summary_->setText(QString("<b>Load notes for %1:</b> none; the scan was read as stored.").arg(name));
    text_->clear();
  } else {
    const std::vector<std::string> all = [this] {
      std::vector<std::string> v;
      for (const QString& n : notices_) v.push_back(n.toStdString());
      return v;
    }();
    const QString first = QString::fromStdString(primaryNotice(all)).toHtmlEscaped();
    summary_->setText(notices_.size() == 1 ? QString("<b>Load note for %1:</b> %2").arg(name, first)
                                           : QString("<b>%1 load notes for %2</b>, first: %3")
                                                 .arg(notices_.size())
                                                 .arg(name, first));
    QString html = "The loader corrected or chose:<ul style=\"margin: 0\">";
    for (const QString& n : notices_) html += "<li>" + n.toHtmlEscaped() + "</li>";
    text_->setText(html + "</ul>");
  }
  summary_->setToolTip(notices_.join("\n"));
  details_->setVisible(notices_.size() > 1);
  setDetailsShown(details_->isChecked());
  phase_row_->setVisible(phase_count_ > 1);
}

}  // namespace vh::ui
