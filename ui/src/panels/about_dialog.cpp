#include "vh/ui/panels/about_dialog.h"

#include <QDialog>
#include <QDialogButtonBox>
#include <QFile>
#include <QJsonArray>
#include <QJsonDocument>
#include <QJsonObject>
#include <QTextBrowser>
#include <QVBoxLayout>

#include "vh/runtime/scene.h"

namespace vh::ui {
namespace {

QByteArray compiledManifest() {
  QFile f(":/vh/datasets/manifest.json");
  return f.open(QIODevice::ReadOnly) ? f.readAll() : QByteArray();
}

}  // namespace

QString aboutHtml(const QByteArray& manifest_json) {
  QString html;
  html += "<h2>VolumeHaptics " VH_VERSION_STRING "</h2>";
  html += "<p>Feel a CT or MR scan with a 6-DOF haptic tool: the tool's proxy rests on the isosurface "
          "you choose and never enters the anatomy.</p>";
  html += "<p>The haptic rendering follows <b>Chan, S., Conti, F., Blevins, N. H., Salisbury, K.</b>: "
          "<i>Constraint-Based Six Degree-Of-Freedom Haptic Rendering of Volume-Embedded Isosurfaces</i>. "
          "IEEE World Haptics Conference (WHC) 2011: a point-shell proxy, continuous collision "
          "detection against the volume's isosurface, a configuration solver after Gauss' principle with "
          "Wilhelmsen's cone projection, and a virtual coupling to the device.</p>";
  html += "<p>Program: BSD 3-Clause licence (see packaging/LICENSE). Built with Qt, VTK and vtkDICOM, "
          "Eigen.</p>";
  const QByteArray text = manifest_json.isEmpty() ? compiledManifest() : manifest_json;
  const QJsonDocument doc = QJsonDocument::fromJson(text);
  const QJsonArray datasets = doc.object().value("datasets").toArray();
  if (!datasets.isEmpty()) {
    html += "<h3>Data</h3><p>" + QString::fromStdString(runtime::sharedDatasetsNote()).toHtmlEscaped() +
            "</p><p>The public datasets the program uses when present there:</p>"
            "<table cellspacing='0' cellpadding='3' border='0'>";
    html += "<tr><th align='left'>dataset</th><th align='left'>credit</th><th align='left'>licence</th></tr>";
    for (const QJsonValue& v : datasets) {
      const QJsonObject d = v.toObject();
      const QString url = d.value("source_url").toString();
      html += QString("<tr><td valign='top'>%1</td><td valign='top'>%2%3</td><td valign='top'>%4</td></tr>")
                  .arg(d.value("id").toString().toHtmlEscaped(), d.value("credit").toString().toHtmlEscaped(),
                       url.isEmpty() ? QString() : QString(" (<a href='%1'>source</a>)").arg(url.toHtmlEscaped()),
                       d.value("licence").toString().toHtmlEscaped());
    }
    html += "</table>";
  } else {
    html += "<p>(The dataset manifest could not be read.)</p>";
  }
  return html;
}

void showAboutDialog(QWidget* parent) {
  QDialog dialog(parent);
  dialog.setWindowTitle("About VolumeHaptics");
  auto* layout = new QVBoxLayout(&dialog);
  auto* browser = new QTextBrowser(&dialog);
  browser->setObjectName("aboutText");
  browser->setOpenExternalLinks(true);
  browser->setHtml(aboutHtml());
  layout->addWidget(browser);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, &dialog);
  QObject::connect(buttons, &QDialogButtonBox::rejected, &dialog, &QDialog::reject);
  layout->addWidget(buttons);
  dialog.resize(720, 560);
  dialog.exec();
}

}  // namespace vh::ui
