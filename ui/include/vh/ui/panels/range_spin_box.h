#pragma once
/// @file
/// A QDoubleSpinBox that never changes a typed value silently. Plain QDoubleSpinBox refuses the
/// keystroke that takes a number out of its range (typing 30 where the maximum is 3.4 leaves
/// "3", committed as 3.00). This one lets the text be typed; a number outside the range is not
/// committed: the box keeps its value and says the range (outOfRange(), and a tooltip at the
/// box), e.g. "30 is outside 0.00 to 3.41: the isovalue stays 0.23". GUI thread only.

#include <QDoubleSpinBox>
#include <QString>

namespace vh::ui {

class RangeSpinBox : public QDoubleSpinBox {
  Q_OBJECT

 public:
  /// @param what names the value in the message ("the isovalue").
  explicit RangeSpinBox(QString what, QWidget* parent = nullptr);

  QValidator::State validate(QString& text, int& pos) const override;
  /// Notes a number out of range before the base restores the value (on Enter or leaving the box).
  void fixup(QString& input) const override;
  /// The message of the last typed value that was out of range ("" none since the last commit).
  const QString& lastRangeMessage() const noexcept { return last_message_; }

 signals:
  /// A typed number outside [minimum(), maximum()] was not taken; `message` says the range.
  void outOfRange(const QString& message);

 private:
  /// On Enter or leaving the box: a number out of range is reported (the value stays).
  void reportTyped();

  QString what_;
  QString last_message_;
  mutable QString pending_typed_;  // an out-of-range number fixup() saw, for reportTyped()
};

}  // namespace vh::ui
