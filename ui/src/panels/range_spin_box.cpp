#include "vh/ui/panels/range_spin_box.h"

#include <memory>
#include <utility>

#include <QLocale>
#include <QPointer>
#include <QToolTip>

namespace vh::ui {

// ---- TypedRange ----------------------------------------------------------------------------------

QString TypedRange::bareNumber(QString text, const QString& prefix, const QString& suffix) {
  if (!prefix.isEmpty() && text.startsWith(prefix)) text.remove(0, prefix.size());
  if (!suffix.isEmpty() && text.endsWith(suffix)) text.chop(suffix.size());
  return text.trimmed();
}

QValidator::State TypedRange::validate(QValidator::State base, std::optional<double> number, double lo, double hi) {
  if (base != QValidator::Invalid) return base;
  // A number the base refuses only for its range: let it stand as typed (not committed).
  return number && (*number < lo || *number > hi) ? QValidator::Intermediate : QValidator::Invalid;
}

void TypedRange::noteTyped(std::optional<double> number, const QString& bare, double lo, double hi) const {
  if (number && (*number < lo || *number > hi)) pending_typed_ = bare;
}

QString TypedRange::report(QWidget& box, const QString& lo_text, const QString& hi_text, const QString& value_text) {
  if (pending_typed_.isEmpty()) {
    last_message_.clear();
    return {};
  }
  last_message_ = QString("%1 is outside %2 to %3: %4 stays %5").arg(pending_typed_, lo_text, hi_text, what_, value_text);
  pending_typed_.clear();
  QToolTip::showText(box.mapToGlobal(QPoint(0, box.height())), last_message_, &box);
  return last_message_;
}

// ---- RangeSpinBox --------------------------------------------------------------------------------

RangeSpinBox::RangeSpinBox(QString what, QWidget* parent) : QDoubleSpinBox(parent), range_(std::move(what)) {
  setKeyboardTracking(false);  // the number typed is taken whole, on Enter or leaving the box
  connect(this, &QAbstractSpinBox::editingFinished, this, [this] {
    const QString message = range_.report(*this, textFromValue(minimum()), textFromValue(maximum()), textFromValue(value()));
    if (!message.isEmpty()) emit outOfRange(message);
  });
}

std::optional<double> RangeSpinBox::typedNumber(const QString& text) const {
  bool ok = false;
  const double v = locale().toDouble(TypedRange::bareNumber(text, prefix(), suffix()), &ok);
  return ok ? std::optional<double>(v) : std::nullopt;
}

QValidator::State RangeSpinBox::validate(QString& text, int& pos) const {
  const QValidator::State state = QDoubleSpinBox::validate(text, pos);
  return state != QValidator::Invalid ? state : TypedRange::validate(state, typedNumber(text), minimum(), maximum());
}

void RangeSpinBox::fixup(QString& input) const {
  range_.noteTyped(typedNumber(input), TypedRange::bareNumber(input, prefix(), suffix()), minimum(), maximum());
  QDoubleSpinBox::fixup(input);
}

// ---- RangeIntSpinBox -----------------------------------------------------------------------------

RangeIntSpinBox::RangeIntSpinBox(QString what, QWidget* parent) : QSpinBox(parent), range_(std::move(what)) {
  setKeyboardTracking(false);  // typing 70000 never takes 7000 on the way
  connect(this, &QAbstractSpinBox::editingFinished, this, [this] {
    const QString message = range_.report(*this, textFromValue(minimum()), textFromValue(maximum()), textFromValue(value()));
    if (!message.isEmpty()) emit outOfRange(message);
  });
}

std::optional<double> RangeIntSpinBox::typedNumber(const QString& text) const {
  bool ok = false;
  const qlonglong v = locale().toLongLong(TypedRange::bareNumber(text, prefix(), suffix()), &ok);
  return ok ? std::optional<double>(static_cast<double>(v)) : std::nullopt;
}

QValidator::State RangeIntSpinBox::validate(QString& text, int& pos) const {
  const QValidator::State state = QSpinBox::validate(text, pos);
  return state != QValidator::Invalid ? state : TypedRange::validate(state, typedNumber(text), minimum(), maximum());
}

void RangeIntSpinBox::fixup(QString& input) const {
  range_.noteTyped(typedNumber(input), TypedRange::bareNumber(input, prefix(), suffix()), minimum(), maximum());
  QSpinBox::fixup(input);
}

// ---- Actions on the values ----------------------------------------------------------------------

std::function<void()> unlessRefused(QObject& context, std::initializer_list<QAbstractSpinBox*> boxes,
                                    std::function<void()> act) {
  struct Refusal {
    QPointer<QWidget> box;
    QString message;
  };
  auto refused = std::make_shared<Refusal>();  // the last refusal since the last try
  for (QAbstractSpinBox* box : boxes) {
    const auto note = [refused, box](const QString& message) { *refused = {box, message}; };
    if (auto* d = qobject_cast<RangeSpinBox*>(box)) QObject::connect(d, &RangeSpinBox::outOfRange, &context, note);
    if (auto* i = qobject_cast<RangeIntSpinBox*>(box)) QObject::connect(i, &RangeIntSpinBox::outOfRange, &context, note);
  }
  return [refused, act = std::move(act)] {
    const Refusal last = std::exchange(*refused, Refusal{});
    if (last.message.isEmpty()) {
      act();
      return;
    }
    // Said again at the box: the click that tried may have hidden the tooltip.
    if (last.box != nullptr) {
      QToolTip::showText(last.box->mapToGlobal(QPoint(0, last.box->height())), last.message, last.box);
      last.box->setFocus();
    }
  };
}

}  // namespace vh::ui
