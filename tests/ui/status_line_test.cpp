// hapticStatusText() and StatusLine: what the status line says in each state of a
// runtime::Session (no scan, haptics off, stopped, starting, running with known numbers,
// replaying).
#include "vh/ui/panels/status_line.h"

#include <memory>

#include <QStatusBar>

#include <gtest/gtest.h>

#include "ui_test_util.h"

#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"

namespace vh::ui {
namespace {

using test::sphereProbeScene;


bool contains(const QString& text, const char* part) { return text.contains(QString::fromUtf8(part)); }

TEST(StatusLine, SaysWhyThereAreNoStatistics) {
  runtime::Session session;
  EXPECT_EQ(hapticStatusText(session, nullptr, {}), "No scan open");

  session.setScene(sphereProbeScene(), nullptr);
  EXPECT_TRUE(hapticStatusText(session, nullptr, {}).startsWith("Haptics off")) << hapticStatusText(session, nullptr, {}).toStdString();

  session.setDevice(std::make_shared<runtime::SimulatedDevice>(sphereProbeScene().X_WT_initial));
  ASSERT_NE(session.hapticThread(), nullptr);
  EXPECT_TRUE(contains(hapticStatusText(session, nullptr, {}), "stopped")) << hapticStatusText(session, nullptr, {}).toStdString();

  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  EXPECT_TRUE(contains(hapticStatusText(session, nullptr, {}), "starting")) << hapticStatusText(session, nullptr, {}).toStdString();
  session.stopHaptics();
}

TEST(StatusLine, ShowsTheSnapshotsNumbers) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), std::make_shared<runtime::SimulatedDevice>(sphereProbeScene().X_WT_initial));
  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  // Each thread sets its scheduling when it starts: realtimeScheduling(), which the line reads,
  // is final once both have ticked (a snapshot with ticks of each), not when start() returns.
  runtime::HapticSnapshot ticked;
  ASSERT_TRUE(test::waitFor(
      [&] {
        session.hapticThread()->latestSnapshot(ticked);
        return ticked.tick > 0 && ticked.solver_tick > 0;
      },
      30000));
  runtime::HapticSnapshot s;
  s.coupling.rate_Hz = 1000.0;
  s.solver.rate_Hz = 250.0;
  s.contacts = 3;
  s.force_W_N = Eigen::Vector3d(1.806, 2.408, 0.0);  // 0.602 * (3, 4, 0): |F| = 3.01 N
  const QString text = hapticStatusText(session, &s, {});
  EXPECT_TRUE(contains(text, "Coupling 1000 Hz")) << text.toStdString();
  EXPECT_TRUE(contains(text, "Solver 250 Hz")) << text.toStdString();
  EXPECT_TRUE(contains(text, "contacts 3")) << text.toStdString();
  EXPECT_TRUE(contains(text, "|F| 3.01 N")) << text.toStdString();
  EXPECT_FALSE(contains(text, "skipped")) << "no skipped samples: not mentioned";
  // Without real-time scheduling (a user outside the group volume-haptics) the line says so and
  // how to get it; with it, nothing.
  EXPECT_EQ(contains(text, "normal priority"), !session.hapticThread()->realtimeScheduling()) << text.toStdString();
  EXPECT_TRUE(schedulingNote(true).isEmpty());
  EXPECT_TRUE(contains(schedulingNote(false), "adduser $USER volume-haptics")) << schedulingNote(false).toStdString();

  // The widget shows the same text in its label, with the misses of the last minute.
  QStatusBar bar;
  StatusLine line(&bar);
  s.coupling.deadline_misses = 7;
  line.showHaptics(session, &s, {});
  MissWindow window;
  window.add(s.time_ns, 7, 0);
  EXPECT_EQ(line.text(), hapticStatusText(session, &s, {}, &window));
  EXPECT_TRUE(contains(line.text(), "misses 7/min")) << line.text().toStdString();
  session.stopHaptics();
}

// The force is the spring between the proxy and the device, the contacts the solver's contact
// set: a force without contacts is the proxy trailing the device, never "contacts 0" beside 8 N.
TEST(StatusLine, AForceWithoutContactsIsSaidToBeTheProxyTrailingNotZeroContacts) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), std::make_shared<runtime::SimulatedDevice>(sphereProbeScene().X_WT_initial));
  session.startHaptics();
  ASSERT_TRUE(session.hapticsRunning());
  runtime::HapticSnapshot s;
  s.coupling.rate_Hz = 1000.0;
  s.solver.rate_Hz = 1000.0;

  s.contacts = 0;
  s.force_W_N = Eigen::Vector3d(0.0, 0.0, 8.0);
  QString text = hapticStatusText(session, &s, {});
  EXPECT_FALSE(contains(text, "contacts 0")) << text.toStdString();
  EXPECT_TRUE(contains(text, "no contact (the proxy trails the device)")) << text.toStdString();
  EXPECT_TRUE(contains(text, "|F| 8.00 N")) << text.toStdString();

  s.force_W_N = Eigen::Vector3d(0.0, 0.01, 0.0);  // the spring settling: free
  text = hapticStatusText(session, &s, {});
  EXPECT_TRUE(contains(text, "|  no contact  |")) << text.toStdString();
  EXPECT_FALSE(contains(text, "trails")) << text.toStdString();

  s.contacts = 5;
  s.force_W_N = Eigen::Vector3d(0.0, 0.0, 8.0);
  text = hapticStatusText(session, &s, {});
  EXPECT_TRUE(contains(text, "contacts 5")) << text.toStdString();
  EXPECT_FALSE(contains(text, "no contact")) << text.toStdString();
  session.stopHaptics();
}

TEST(StatusLine, DeadlineMissesAreCountedOverTheLastMinuteNotSinceTheStart) {
  constexpr std::int64_t s = 1000000000;
  MissWindow w;
  w.add(0, 100, 5);  // the threads missed 100 and 5 since they started
  EXPECT_EQ(w.coupling(), 100u);
  EXPECT_EQ(w.solver(), 5u);
  w.add(30 * s, 100, 5);
  EXPECT_EQ(w.coupling(), 100u) << "within the first minute: since the start";
  w.add(61 * s, 100, 5);
  EXPECT_EQ(w.coupling(), 0u) << "none in the last minute";
  w.add(90 * s, 103, 5);
  EXPECT_EQ(w.coupling(), 3u);
  EXPECT_EQ(w.solver(), 0u);
  w.add(200 * s, 103, 6);
  EXPECT_EQ(w.coupling(), 0u) << "the 3 misses at 90 s are more than a minute old";
  EXPECT_EQ(w.solver(), 1u);
  w.add(201 * s, 2, 0);  // new threads: totals start again
  EXPECT_EQ(w.coupling(), 2u);
  EXPECT_EQ(w.solver(), 0u);
}

TEST(StatusLine, AReplayNamesTheRecording) {
  runtime::Session session;
  session.setScene(sphereProbeScene(), nullptr);
  const QString text = hapticStatusText(session, nullptr, "probe-run.vhrec");
  EXPECT_TRUE(text.startsWith("Replaying probe-run.vhrec")) << text.toStdString();
  EXPECT_EQ(hapticStatusText(runtime::Session{}, nullptr, "probe-run.vhrec"), "No scan open");
}

}  // namespace
}  // namespace vh::ui
