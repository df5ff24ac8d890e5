#pragma once
/// @file
/// Spin boxes that never change a typed value silently. A plain QDoubleSpinBox or QSpinBox
/// refuses the keystroke that takes a number out of its range (typing 30 where the maximum is
/// 3.4 leaves "3", committed as 3.00). These let the text be typed and take it whole, on Enter or
/// on leaving the box (no keyboard tracking: typing 70000 in a port never takes 7000 on the way);
/// a number outside the range is not committed: the box keeps its value and says the range
/// (outOfRange(), and a tooltip at the box), e.g. "30 is outside 0.00 to 3.41: the isovalue stays
/// 0.23". RangeSpinBox is the decimal
/// one, RangeIntSpinBox the integer one (ports, time points); both take their logic from
/// TypedRange. In a dialog, unlessRefused() keeps the dialog open when OK (or Enter) comes right
/// after a refused number, so that the message is seen. GUI thread only.

#include <functional>
#include <initializer_list>
#include <optional>
#include <utility>

#include <QDoubleSpinBox>
#include <QSpinBox>
#include <QString>


namespace vh::ui {

/// What RangeSpinBox and RangeIntSpinBox share (their Qt bases differ): which typed numbers are
/// let stand as typed, which are noted as refused, and the message that says the range.
class TypedRange {
 public:
  /// @param what names the value in the message ("the isovalue", "the port").
  explicit TypedRange(QString what) : what_(std::move(what)) {}

  /// `text` without the box's `prefix`, `suffix` and surrounding spaces.
  static QString bareNumber(QString text, const QString& prefix, const QString& suffix);
  /// A box's validate(): `base` (its Qt base's answer) unless the base refuses `number` (the
  /// text parsed; nullopt: not a number) only because it lies outside [lo, hi]: then
  /// Intermediate (typed, not committed). A number in range that the base refuses (more decimals
  /// than the box has) stays refused, keystroke by keystroke as the base does.
  static QValidator::State validate(QValidator::State base, std::optional<double> number, double lo, double hi);
  /// Before the base's fixup() (Enter or leaving the box): notes `number` (typed as `bare`) when
  /// it lies outside [lo, hi], for report().
  void noteTyped(std::optional<double> number, const QString& bare, double lo, double hi) const;
  /// After editingFinished(): the message for the number noted, shown as a tooltip at `box` ("" when
  /// none was noted; the last message is then cleared), the range and the value kept as the box
  /// writes them.
  QString report(QWidget& box, const QString& lo_text, const QString& hi_text, const QString& value_text);
  /// The message of the last typed value that was out of range ("" none since the last commit).
  const QString& lastMessage() const noexcept { return last_message_; }

 private:
  QString what_;
  QString last_message_;
  mutable QString pending_typed_;  // an out-of-range number noteTyped() saw, for report()
};

/// A QDoubleSpinBox that never changes a typed value silently (see the file's comment).
class RangeSpinBox : public QDoubleSpinBox {
  Q_OBJECT

 public:
  /// @param what names the value in the message ("the isovalue").
  explicit RangeSpinBox(QString what, QWidget* parent = nullptr);

  QValidator::State validate(QString& text, int& pos) const override;
  /// Notes a number out of range before the base restores the value (on Enter or leaving the box).
  void fixup(QString& input) const override;
  /// The message of the last typed value that was out of range ("" none since the last commit).
  const QString& lastRangeMessage() const noexcept { return range_.lastMessage(); }

 signals:
  /// A typed number outside [minimum(), maximum()] was not taken; `message` says the range.
  void outOfRange(const QString& message);

 private:
  std::optional<double> typedNumber(const QString& text) const;
  TypedRange range_;
};

/// The integer sibling of RangeSpinBox: a QSpinBox (value() an int) that never changes a typed
/// value silently. A number with a fraction is refused keystroke by keystroke, as by QSpinBox.
class RangeIntSpinBox : public QSpinBox {
  Q_OBJECT

 public:
  /// @param what names the value in the message ("the port").
  explicit RangeIntSpinBox(QString what, QWidget* parent = nullptr);

  QValidator::State validate(QString& text, int& pos) const override;
  void fixup(QString& input) const override;
  const QString& lastRangeMessage() const noexcept { return range_.lastMessage(); }

 signals:
  /// A typed number outside [minimum(), maximum()] was not taken; `message` says the range.
  void outOfRange(const QString& message);

 private:
  std::optional<double> typedNumber(const QString& text) const;
  TypedRange range_;
};

/// `act` (a dialog's accept(), a Load button's action), held back once when one of `boxes`
/// (RangeSpinBox or RangeIntSpinBox) has refused a typed number since the last try: Enter in the
/// box, or a click on OK while the number was still typed, would otherwise act on the value kept
/// (and close a dialog, taking the message at the box with it). Held back, the message is said at
/// the box again; the next try acts on the values the boxes show. Connect the result to the
/// trigger (QDialogButtonBox::accepted, QPushButton::clicked); `context` outlives the boxes'
/// connections (the dialog or panel).
std::function<void()> unlessRefused(QObject& context, std::initializer_list<QAbstractSpinBox*> boxes,
                                    std::function<void()> act);

}  // namespace vh::ui
