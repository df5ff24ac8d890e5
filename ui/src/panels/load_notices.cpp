#include "vh/ui/panels/load_notices.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <iostream>
#include <string_view>

#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QSpinBox>
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
  // Key phrases of io's notices, most important first.
  static constexpr std::array<std::string_view, 9> kOrder = {"gantry tilt", "sheared",  "missing slice",
                                                             "spacing",     "resampled", "duplicate",
                                                             "skipped",     "time point", "series"};
  const std::string text = lower(notice);
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
  QString text = "Note: " + QString::fromStdString(first);
  if (notices.size() > 1) text += QString(" (+%1 more, see Help > Load Notes)").arg(notices.size() - 1);
  return text;
}

LoadNoticePanel::LoadNoticePanel(QWidget* parent)
    : QFrame(parent),
      text_(new QLabel(this)),
      close_(new QToolButton(this)),
      phase_row_(new QWidget(this)),
      phase_label_(new QLabel(phase_row_)),
      phase_spin_(new QSpinBox(phase_row_)),
      phase_load_(new QPushButton("Load This Time Point", phase_row_)) {
  setObjectName("loadNoticePanel");
  setFrameShape(QFrame::StyledPanel);
  // Amber, as a notice that is not an error; dark text whatever the palette.
  setStyleSheet(
      "#loadNoticePanel { background: #fff4ce; border: 1px solid #d9a400; border-radius: 3px; }"
      "#loadNoticePanel QLabel { color: #3a2e00; }");
  text_->setObjectName("loadNoticeText");
  text_->setWordWrap(true);
  text_->setTextFormat(Qt::RichText);
  text_->setTextInteractionFlags(Qt::TextSelectableByMouse);
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

  auto* column = new QVBoxLayout();
  column->addWidget(text_);
  column->addWidget(phase_row_);
  auto* layout = new QHBoxLayout(this);
  layout->setContentsMargins(8, 4, 4, 4);
  layout->addLayout(column, 1);
  layout->addWidget(close_, 0, Qt::AlignTop);

  connect(close_, &QToolButton::clicked, this, &QWidget::hide);
  connect(phase_load_, &QPushButton::clicked, this, [this] {
    runtime::SceneSpec spec = spec_;
    spec.volume.phase = phase_spin_->value() - 1;
    emit reloadRequested(spec, opened_);
  });
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
  refresh();
  setVisible(!notices_.isEmpty() || phase_count_ > 1);
}

void LoadNoticePanel::reopen() {
  refresh();
  show();
}

void LoadNoticePanel::refresh() {
  const QString name = title_.isEmpty() ? QString("the volume") : title_.toHtmlEscaped();
  QString html;
  if (notices_.isEmpty()) {
    html = QString("<b>Load notes for %1:</b> none; the scan was read as stored.").arg(name);
  } else {
    html = QString("<b>Load notes for %1</b> - the loader corrected or chose:<ul style=\"margin: 0\">").arg(name);
    for (const QString& n : notices_) html += "<li>" + n.toHtmlEscaped() + "</li>";
    html += "</ul>";
  }
  text_->setText(html);
  phase_row_->setVisible(phase_count_ > 1);
}

}  // namespace vh::ui
