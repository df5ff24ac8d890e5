#include "vh/ui/panels/range_spin_box.h"

#include <QLineEdit>
#include <QLocale>
#include <QToolTip>

namespace vh::ui {
namespace {

/// `text` without the spin box's prefix, suffix and spaces.
QString bareNumber(const QDoubleSpinBox& box, QString text) {
  if (!box.prefix().isEmpty() && text.startsWith(box.prefix())) text.remove(0, box.prefix().size());
  if (!box.suffix().isEmpty() && text.endsWith(box.suffix())) text.chop(box.suffix().size());
  return text.trimmed();
}

}  // namespace

RangeSpinBox::RangeSpinBox(QString what, QWidget* parent) : QDoubleSpinBox(parent), what_(std::move(what)) {
  connect(this, &QAbstractSpinBox::editingFinished, this, &RangeSpinBox::reportTyped);
}

QValidator::State RangeSpinBox::validate(QString& text, int& pos) const {
  const QValidator::State state = QDoubleSpinBox::validate(text, pos);
  if (state != QValidator::Invalid) return state;
  // A number the base refuses only for its range: let it stand as typed (not committed).
  bool ok = false;
  (void)locale().toDouble(bareNumber(*this, text), &ok);
  return ok ? QValidator::Intermediate : QValidator::Invalid;
}

void RangeSpinBox::fixup(QString& input) const {
  bool ok = false;
  const double typed = locale().toDouble(bareNumber(*this, input), &ok);
  if (ok && (typed < minimum() || typed > maximum())) pending_typed_ = bareNumber(*this, input);
  QDoubleSpinBox::fixup(input);
}

void RangeSpinBox::reportTyped() {
  if (pending_typed_.isEmpty()) {
    last_message_.clear();
    return;
  }
  last_message_ = QString("%1 is outside %2 to %3: %4 stays %5")
                      .arg(pending_typed_, textFromValue(minimum()), textFromValue(maximum()), what_, textFromValue(value()));
  pending_typed_.clear();
  QToolTip::showText(mapToGlobal(QPoint(0, height())), last_message_, this);
  emit outOfRange(last_message_);
}

}  // namespace vh::ui
