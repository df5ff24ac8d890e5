// Tests of vh/ui/igtl_panel.h: the OpenIGTLink switch off by default, on with a port and rate,
// its status-bar text, and an IMAGE sent by a client opening as the main window's new scene.
#include "vh/ui/panels/igtl_panel.h"

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>

#include <gtest/gtest.h>
#include <QLabel>
#include <QSignalSpy>
#include <QStatusBar>

#include <igtlClientSocket.h>
#include <igtlImageMessage.h>

#include "ui_test_util.h"
#include "vh/runtime/recording.h"
#include "vh/ui/main_window.h"
#include "vh/ui/replay/session_recorder.h"

namespace vh::ui {
namespace {

using test::waitFor;

/// A port no one listens on now (probed with a plain socket; pid-dependent start).
int freePort() {
  static int next = 30000 + static_cast<int>(getpid() % 2000) * 10;
  for (int tries = 0; tries < 500; ++tries) {
    const int port = next++;
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    const bool ok = bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
    close(fd);
    if (ok) return port;
  }
  return 0;
}

TEST(IgtlPanel, ClampsTheSettings) {
  const IgtlSettings s = clampIgtlSettings({true, 70000, 5000.0, "127.0.0.1", {}}, 1000.0);
  EXPECT_EQ(s.port, 65535);
  EXPECT_DOUBLE_EQ(s.rate_Hz, 1000.0);
  EXPECT_DOUBLE_EQ(clampIgtlSettings({true, 0, 0.1, "127.0.0.1", {}}, 1000.0).rate_Hz, 1.0);
  EXPECT_EQ(clampIgtlSettings({true, 0, 0.1, "127.0.0.1", {}}, 1000.0).port, 1);
  EXPECT_DOUBLE_EQ(clampIgtlSettings({true, 18944, std::nan(""), "127.0.0.1", {}}, 1000.0).rate_Hz, 60.0);
}

TEST(IgtlPanel, OffByDefaultThenListensWithItsStatusInTheStatusBar) {
  QStatusBar bar;
  IgtlPanel panel(&bar, 1000.0, nullptr);
  EXPECT_FALSE(panel.running());
  EXPECT_FALSE(panel.settings().enabled);
  EXPECT_EQ(panel.statusText(), "OpenIGTLink off");
  auto* label = bar.findChild<QLabel*>("igtlStatus");
  ASSERT_NE(label, nullptr);
  EXPECT_TRUE(label->isHidden());

  const int port = freePort();
  QString error;
  ASSERT_TRUE(panel.apply({true, port, 120.0, "127.0.0.1", {}}, &error)) << error.toStdString();
  EXPECT_TRUE(panel.running());
  EXPECT_DOUBLE_EQ(panel.link()->rate_Hz(), 120.0);
  EXPECT_EQ(panel.statusText(), QString("OpenIGTLink: listening on 127.0.0.1:%1").arg(port));
  EXPECT_EQ(label->text(), panel.statusText());

  // A second server on the same port fails with the reason, and stays off.
  IgtlPanel other(&bar, 1000.0, nullptr);
  EXPECT_FALSE(other.apply({true, port, 60.0, "127.0.0.1", {}}, &error));
  EXPECT_TRUE(error.contains(QString("cannot listen on 127.0.0.1:%1").arg(port))) << error.toStdString();
  EXPECT_FALSE(other.running());

  // A client connects: the label says so.
  signal(SIGPIPE, SIG_IGN);
  ::igtl::ClientSocket::Pointer client = ::igtl::ClientSocket::New();
  ASSERT_EQ(client->ConnectToServer("127.0.0.1", port), 0);
  ASSERT_TRUE(waitFor([&] { panel.poll(); return label->text().contains("connected to 127.0.0.1"); }, 30000))
      << label->text().toStdString();

  ASSERT_TRUE(panel.apply({false, port, 120.0, "127.0.0.1", {}}));
  EXPECT_FALSE(panel.running());
  EXPECT_TRUE(label->isHidden());
}

TEST(IgtlPanel, ImageFromAClientOpensAsTheNewScene) {
  MainWindow window;
  window.setInteractive(false);
  window.resize(800, 600);
  window.show();
  EXPECT_FALSE(window.igtlPanel()->running()) << "off by default";
  EXPECT_EQ(window.session().monitor(), window.igtlPanel()->channel()) << "the session feeds the link's channel";
  const int port = freePort();
  ASSERT_TRUE(window.igtlPanel()->apply({true, port, 60.0, "127.0.0.1", {}}));
  QSignalSpy loaded(&window, &MainWindow::sceneLoaded);
  std::vector<IgtlVolumeOffer> offers;
  bool answer = false;
  window.igtlPanel()->setConfirmVolume([&](const IgtlVolumeOffer& offer) {
    offers.push_back(offer);
    return answer;
  });

  // A 24 x 20 x 16 float volume: a ball of radius 5 mm (F = 5 - r [mm]) at spacing (0.8, 0.9,
  // 1.0) mm, axes along RAS, first voxel at (-10, 20, -5) mm RAS.
  signal(SIGPIPE, SIG_IGN);
  ::igtl::ImageMessage::Pointer image = ::igtl::ImageMessage::New();
  const int n[3] = {24, 20, 16};
  const float sp[3] = {0.8f, 0.9f, 1.0f};
  image->SetDimensions(n[0], n[1], n[2]);
  image->SetSpacing(sp[0], sp[1], sp[2]);
  image->SetScalarType(::igtl::ImageMessage::TYPE_FLOAT32);
  image->SetEndian(::igtl::ImageMessage::ENDIAN_LITTLE);
  image->SetDeviceName("Ball");
  image->SetOrigin(-10.0f + 0.5f * 23 * 0.8f, 20.0f + 0.5f * 19 * 0.9f, -5.0f + 0.5f * 15 * 1.0f);  // the centre
  image->AllocateScalars();
  auto* v = static_cast<float*>(image->GetScalarPointer());
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) {
        const double x = (i - 11.5) * 0.8, y = (j - 9.5) * 0.9, z = (k - 7.5) * 1.0;
        v[i + n[0] * (j + n[1] * k)] = static_cast<float>(5.0 - std::sqrt(x * x + y * y + z * z));
      }
    }
  }
  image->Pack();
  ::igtl::ClientSocket::Pointer client = ::igtl::ClientSocket::New();
  ASSERT_EQ(client->ConnectToServer("127.0.0.1", port), 0);

  // Declined: nothing opens.
  ASSERT_EQ(client->Send(image->GetPackPointer(), image->GetPackSize()), 1);
  ASSERT_TRUE(waitFor([&] { return offers.size() == 1; }, 30000));
  EXPECT_EQ(offers[0].peer.rfind("127.0.0.1:", 0), 0u) << offers[0].peer;
  EXPECT_EQ(offers[0].name, "Ball");
  EXPECT_EQ(offers[0].dims, (std::array<int, 3>{24, 20, 16}));
  EXPECT_NEAR(offers[0].spacing_mm.x(), 0.8, 1e-6);
  EXPECT_NEAR(offers[0].spacing_mm.z(), 1.0, 1e-6);
  EXPECT_FALSE(offers[0].recording);
  const QString text = igtlOfferText(offers[0]);
  EXPECT_TRUE(text.contains("24 x 20 x 16 voxels") && text.contains("sent by 127.0.0.1:")) << text.toStdString();
  EXPECT_FALSE(waitFor([&] { return loaded.count() > 0; }, 500));
  EXPECT_FALSE(window.hasScene());

  // Accepted: it opens.
  answer = true;
  ASSERT_EQ(client->Send(image->GetPackPointer(), image->GetPackSize()), 1);
  ASSERT_TRUE(waitFor([&] { return loaded.count() > 0; }, 30000)) << window.opener()->lastError().toStdString();
  ASSERT_TRUE(window.hasScene());
  const haptics::VolumeGeometry& g = window.session().loaded().volume.field->geometry();
  EXPECT_EQ(g.dims, (std::array<int, 3>{24, 20, 16}));
  EXPECT_NEAR(g.spacing_m.x(), 0.0008, 1e-9);
  EXPECT_NEAR(g.origin_W_m.x(), 0.010, 1e-6);   // R -10 mm is L +10 mm
  EXPECT_NEAR(g.origin_W_m.y(), -0.020, 1e-6);  // A 20 mm is P -20 mm
  EXPECT_NEAR(g.origin_W_m.z(), -0.005, 1e-6);
  EXPECT_EQ(window.session().loaded().volume.info.format, "OpenIGTLink");
  EXPECT_EQ(window.session().loaded().spec.volume.path, "igtl:Ball");
  EXPECT_TRUE(window.preferences().recent_files.isEmpty() ||
              !window.preferences().recent_files.front().contains("igtl:"));
  // Its haptics feed the link.
  runtime::HapticSnapshot s;
  ASSERT_TRUE(waitFor([&] { return window.session().hapticsRunning(); }, 30000));
  EXPECT_TRUE(waitFor([&] { return window.igtlPanel()->channel()->read(s) && s.tick > 20; }, 30000));

  // While a recording runs: the question says it will end; the recording is ended with a
  // marker saying why and read back whole, before the new scene. (A scene sent over the link
  // has no file to replay from and is not recorded: the recording runs on a scene from a file.)
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir());
  const std::filesystem::path scene_file = dir / "igtl_panel_sphere.json";
  {
    std::ofstream out(scene_file);
    out << R"({"volume": {"path": "builtin:sphere"}, "tool": {"mesh": "builtin:probe"}, "device": {"kind": "simulated"}})";
  }
  loaded.clear();
  window.openPath(QString::fromStdString(scene_file.string()));
  ASSERT_TRUE(waitFor([&] { return loaded.count() > 0; }, 30000)) << window.opener()->lastError().toStdString();
  ASSERT_EQ(window.session().loaded().spec.volume.path, "builtin:sphere");
  ASSERT_TRUE(waitFor([&] { return window.session().hapticsRunning(); }, 30000));
  const std::filesystem::path rec = dir / "igtl_panel_recording.vhrec";
  ASSERT_TRUE(window.recorder()->start(rec)) << window.recorder()->lastError().toStdString();
  ASSERT_TRUE(waitFor([&] { return window.recorder()->recordsWritten() > 100; }, 30000));
  loaded.clear();
  ASSERT_EQ(client->Send(image->GetPackPointer(), image->GetPackSize()), 1);
  ASSERT_TRUE(waitFor([&] { return loaded.count() > 0; }, 30000));
  ASSERT_EQ(offers.size(), 3u);
  EXPECT_TRUE(offers[2].recording);
  EXPECT_TRUE(igtlOfferText(offers[2]).contains("recording in progress will be ended"));
  EXPECT_FALSE(window.recorder()->recording());
  const runtime::Recording read = runtime::readRecording(rec);
  EXPECT_TRUE(read.warnings.empty());
  EXPECT_GT(read.records.size(), 100u);
  bool why = false;
  for (const runtime::RecordingEvent& e : read.events) why = why || e.detail_json.find("OpenIGTLink") != std::string::npos;
  EXPECT_TRUE(why) << "the recording does not say why it ended";
  window.session().stopHaptics();
}

}  // namespace
}  // namespace vh::ui
