#include "vh/ui/preferences.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include <QSettings>

#include "vh/io/private_files.h"

namespace vh::ui {
namespace {

QColor readColour(QSettings& s, const char* key, const QColor& fallback) {
  const QColor c(s.value(key, fallback.name()).toString());
  return c.isValid() ? c : fallback;
}

double readPositive(QSettings& s, const char* key, double fallback) {
  bool ok = false;
  const double v = s.value(key, fallback).toDouble(&ok);
  return ok && std::isfinite(v) && v >= 0.0 ? v : fallback;
}

}  // namespace

void Preferences::addRecentFile(const QString& path) {
  if (path.isEmpty()) return;
  recent_files.removeAll(path);
  recent_files.prepend(path);
  while (recent_files.size() > kMaxRecentFiles) recent_files.removeLast();
}

Preferences Preferences::load(QSettings& s) {
  Preferences p;
  s.beginGroup("preferences");
  p.background_bottom = readColour(s, "colours/background_bottom", p.background_bottom);
  p.background_top = readColour(s, "colours/background_top", p.background_top);
  p.surface = readColour(s, "colours/surface", p.surface);
  p.tool = readColour(s, "colours/tool", p.tool);
  p.device = readColour(s, "colours/device", p.device);
  p.linear_stiffness_N_per_m = readPositive(s, "haptics/linear_stiffness_N_per_m", p.linear_stiffness_N_per_m);
  p.torsional_stiffness_Nm_per_rad =
      readPositive(s, "haptics/torsional_stiffness_Nm_per_rad", p.torsional_stiffness_Nm_per_rad);
  p.passivity_control = s.value("haptics/passivity_control", p.passivity_control).toBool();
  const int mode = s.value("view/mode", static_cast<int>(p.mode)).toInt();
  if (mode >= 0 && mode <= static_cast<int>(RenderMode::kMip)) p.mode = static_cast<RenderMode>(mode);
  const int preset = s.value("view/preset", static_cast<int>(p.preset)).toInt();
  if (preset >= 0 && preset <= static_cast<int>(VolumePreset::kSkin)) p.preset = static_cast<VolumePreset>(preset);
  p.orientation_marker = s.value("view/orientation_marker", p.orientation_marker).toBool();
  p.show_device = s.value("view/show_device", p.show_device).toBool();
  p.tool_shadow = s.value("view/tool_shadow", p.tool_shadow).toBool();
  p.segments_through_scan = s.value("view/segments_through_scan", p.segments_through_scan).toBool();
  p.burr_sound = s.value("sound/burr", p.burr_sound).toBool();
  p.alert_sound = s.value("sound/alert", p.alert_sound).toBool();
  p.recent_files = s.value("files/recent").toStringList();
  while (p.recent_files.size() > kMaxRecentFiles) p.recent_files.removeLast();
  p.last_folder = s.value("files/last_folder").toString();
  p.datasets_dir = s.value("files/datasets_dir").toString();
  p.pacs.host = s.value("pacs/host", QString::fromStdString(p.pacs.host)).toString().toStdString();
  const int port = s.value("pacs/port", p.pacs.port).toInt();
  if (port >= 1 && port <= 65535) p.pacs.port = port;
  p.pacs.called_aet = s.value("pacs/called_aet", QString::fromStdString(p.pacs.called_aet)).toString().toStdString();
  p.pacs.calling_aet = s.value("pacs/calling_aet", QString::fromStdString(p.pacs.calling_aet)).toString().toStdString();
  const int timeout = s.value("pacs/timeout_s", p.pacs.timeout_s).toInt();
  if (timeout >= 1 && timeout <= 3600) p.pacs.timeout_s = timeout;
  p.pacs.tls = s.value("pacs/tls", p.pacs.tls).toBool();
  p.pacs.ca_cert = s.value("pacs/ca_cert").toString().toStdString();
  p.pacs.client_cert = s.value("pacs/client_cert").toString().toStdString();
  p.pacs.client_key = s.value("pacs/client_key").toString().toStdString();
  s.endGroup();
  return p;
}

void Preferences::save(QSettings& s) const {
  s.beginGroup("preferences");
  s.setValue("colours/background_bottom", background_bottom.name());
  s.setValue("colours/background_top", background_top.name());
  s.setValue("colours/surface", surface.name());
  s.setValue("colours/tool", tool.name());
  s.setValue("colours/device", device.name());
  s.setValue("haptics/linear_stiffness_N_per_m", linear_stiffness_N_per_m);
  s.setValue("haptics/torsional_stiffness_Nm_per_rad", torsional_stiffness_Nm_per_rad);
  s.setValue("haptics/passivity_control", passivity_control);
  s.setValue("view/mode", static_cast<int>(mode));
  s.setValue("view/preset", static_cast<int>(preset));
  s.setValue("view/orientation_marker", orientation_marker);
  s.setValue("view/show_device", show_device);
  s.setValue("view/tool_shadow", tool_shadow);
  s.setValue("view/segments_through_scan", segments_through_scan);
  s.setValue("sound/burr", burr_sound);
  s.setValue("sound/alert", alert_sound);
  s.setValue("files/recent", recent_files);
  s.setValue("files/last_folder", last_folder);
  s.setValue("files/datasets_dir", datasets_dir);
  s.setValue("pacs/host", QString::fromStdString(pacs.host));
  s.setValue("pacs/port", pacs.port);
  s.setValue("pacs/called_aet", QString::fromStdString(pacs.called_aet));
  s.setValue("pacs/calling_aet", QString::fromStdString(pacs.calling_aet));
  s.setValue("pacs/timeout_s", pacs.timeout_s);
  s.setValue("pacs/tls", pacs.tls);
  s.setValue("pacs/ca_cert", QString::fromStdString(pacs.ca_cert));
  s.setValue("pacs/client_cert", QString::fromStdString(pacs.client_cert));
  s.setValue("pacs/client_key", QString::fromStdString(pacs.client_key));
  s.endGroup();
}

void makeSettingsPrivate() noexcept {
  try {
    const std::filesystem::path file = QSettings().fileName().toStdString();
    if (file.empty() || !file.has_parent_path()) return;
    io::createPrivateDirectories(file.parent_path());
    ::chmod(file.parent_path().c_str(), 0700);  // the application's own folder, also when it existed
    ::close(io::openPrivateFile(file, /*append=*/true));  // created 0600, or made 0600, never truncated
  } catch (...) {  // NOLINT(bugprone-empty-catch): best effort, the settings still work
  }
}

}  // namespace vh::ui
