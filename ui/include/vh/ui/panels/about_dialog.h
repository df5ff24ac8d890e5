#pragma once
/// @file
/// The About box: what the program does, the paper it implements (Chan, Conti, Blevins,
/// Salisbury, WHC 2011), the project's licence, and the source, credit and licence of every
/// public dataset in datasets/manifest.json (compiled into the program as a Qt resource).

#include <QString>

class QWidget;

namespace vh::ui {

/// The About text (HTML). `manifest_json` is the text of datasets/manifest.json; empty: the
/// compiled-in copy.
QString aboutHtml(const QByteArray& manifest_json = {});

/// Shows the About box (modal).
void showAboutDialog(QWidget* parent);

}  // namespace vh::ui
