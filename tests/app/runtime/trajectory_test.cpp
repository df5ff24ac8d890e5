// Tests of vh/runtime/trajectory.h and ScriptedDevice: CSV parsing (good and every error),
// interpolation (lerp + slerp), the CSV round trip, and the push-and-slide generator against an
// analytic plane.
#include "vh/runtime/trajectory.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "runtime_test_support.h"
#include "vh/datasets/synthetic.h"
#include "vh/runtime/device.h"
#include "vh/runtime/placement.h"

namespace vh::runtime {
namespace {

namespace fs = std::filesystem;
using haptics::Pose;

Trajectory parse(const std::string& text) {
  std::istringstream in(text);
  return parseTrajectoryCsv(in, "t.csv");
}

Eigen::Quaterniond aboutZ(double angle_rad) { return Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ())); }

TEST(TrajectoryCsv, ParsesHeaderCommentsBlankLinesAndCrlf) {
  const Trajectory t = parse(
      "# recorded by hand\r\n"
      "t_s,x_m,y_m,z_m,qw,qx,qy,qz\r\n"
      "\r\n"
      "0.0, 0.1, 0.2, 0.3, 2, 0, 0, 0\r\n"
      "  # a comment between rows\n"
      "0.5,1e-3,-2e-3,+3e-3,0,0,0,1\n");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.startTime_s(), 0.0);
  EXPECT_DOUBLE_EQ(t.endTime_s(), 0.5);
  EXPECT_TRUE(t.samples()[0].X_WD.p_AB_m.isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));
  EXPECT_DOUBLE_EQ(t.samples()[0].X_WD.R_AB.w(), 1.0);  // normalised from 2
  EXPECT_TRUE(t.samples()[1].X_WD.p_AB_m.isApprox(Eigen::Vector3d(1e-3, -2e-3, 3e-3)));
  EXPECT_DOUBLE_EQ(t.samples()[1].X_WD.R_AB.z(), 1.0);
}

TEST(TrajectoryCsv, HeaderIsOptional) {
  const Trajectory t = parse("1,0,0,0,1,0,0,0\n2,1,0,0,1,0,0,0\n");
  EXPECT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.duration_s(), 1.0);
}

TEST(TrajectoryCsvErrors, NameSourceAndLine) {
  VH_EXPECT_THROW_WITH(parse("t_s,x_m,y_m,z_m,qw,qx,qy,qz\n0,0,0,0,1,0,0\n"), std::runtime_error,
                       "t.csv:2: expected 8 comma-separated values", "found 7");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,1,0,0,0\n\n1,0,abc,0,1,0,0,0\n"), std::runtime_error,
                       "t.csv:3: column y_m: 'abc' is not a number");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,1,0,0,0\n1,0,0,0,1,0,0,0x\n"), std::runtime_error,
                       "t.csv:2: column qz: '0x' is not a number");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,1,0,0,0\n1,nan,0,0,1,0,0,0\n"), std::runtime_error,
                       "t.csv:2: column x_m: value is not finite");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,1,0,0,0\n0.5,0,0,0,1,0,0,0\n0.5,0,0,0,1,0,0,0\n"), std::runtime_error,
                       "t.csv:3: time 0.5 s does not increase");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,0,0,0,0\n"), std::runtime_error, "t.csv:1: zero quaternion");
  VH_EXPECT_THROW_WITH(parse("time,x,y,z,qw,qx,qy,qz\n"), std::runtime_error, "t.csv:1: header must be");
  VH_EXPECT_THROW_WITH(parse("# nothing\n\n"), std::runtime_error, "t.csv: no samples");
  VH_EXPECT_THROW_WITH(loadTrajectoryCsv("/no/such/t.csv"), std::runtime_error, "/no/such/t.csv", "not found");
}

TEST(TrajectoryCsv, TheNinthColumnGivesTheIsovalueBlankMeansTheScenes) {
  const Trajectory t = parse(
      "t_s,x_m,y_m,z_m,qw,qx,qy,qz,isovalue\n"
      "0,0,0,0,1,0,0,0,\n"
      "1,0,0,0,1,0,0,0,500\n"
      "2,0,0,0,1,0,0,0,-250.5\n");
  ASSERT_EQ(t.size(), 3u);
  EXPECT_TRUE(std::isnan(t.samples()[0].isovalue));
  EXPECT_EQ(t.samples()[1].isovalue, 500.0);
  EXPECT_EQ(t.samples()[2].isovalue, -250.5);
  EXPECT_TRUE(t.hasIsovalues());
  // Linear between keys; the blank key counts as the fallback (the scene's isovalue, here 100).
  EXPECT_DOUBLE_EQ(t.isovalueAt(0.0, 100.0), 100.0);
  EXPECT_DOUBLE_EQ(t.isovalueAt(0.5, 100.0), 300.0);
  EXPECT_DOUBLE_EQ(t.isovalueAt(1.5, 100.0), 124.75);
  EXPECT_DOUBLE_EQ(t.isovalueAt(9.0, 100.0), -250.5);
  EXPECT_DOUBLE_EQ(t.isovalueAt(-1.0, 100.0), 100.0);
  // The 8-column form has none: always the fallback.
  const Trajectory eight = parse("t_s,x_m,y_m,z_m,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,0,0,0,1,0,0,0\n");
  EXPECT_FALSE(eight.hasIsovalues());
  EXPECT_DOUBLE_EQ(eight.isovalueAt(0.5, 7.0), 7.0);
  // Without a header, rows of 8 and 9 values mix.
  const Trajectory mixed = parse("0,0,0,0,1,0,0,0\n1,0,0,0,1,0,0,0,3\n");
  EXPECT_DOUBLE_EQ(mixed.isovalueAt(1.0, 0.0), 3.0);
}

TEST(TrajectoryCsvErrors, BadIsovaluesAndColumnCountsNameTheLine) {
  VH_EXPECT_THROW_WITH(parse("t_s,x_m,y_m,z_m,qw,qx,qy,qz,isovalue\n0,0,0,0,1,0,0,0,1\n1,0,0,0,1,0,0,0,abc\n"),
                       std::runtime_error, "t.csv:3: column isovalue: 'abc' is not a number");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,1,0,0,0,inf\n"), std::runtime_error, "t.csv:1: column isovalue: value is not finite");
  VH_EXPECT_THROW_WITH(parse("t_s,x_m,y_m,z_m,qw,qx,qy,qz\n0,0,0,0,1,0,0,0,5\n"), std::runtime_error,
                       "t.csv:2: expected 8 comma-separated values", "as the header says", "found 9");
  VH_EXPECT_THROW_WITH(parse("t_s,x_m,y_m,z_m,qw,qx,qy,qz,isovalue\n\n0,0,0,0,1,0,0,0\n"), std::runtime_error,
                       "t.csv:3: expected 9 comma-separated values", "found 8");
  VH_EXPECT_THROW_WITH(parse("0,0,0,0,1,0,0,0,1,2\n"), std::runtime_error, "t.csv:1: expected 8 or 9", "found 10");
  VH_EXPECT_THROW_WITH(parse("t_s,x_m,y_m,z_m,qw,qx,qy,qz,iso\n"), std::runtime_error, "t.csv:1: header must be",
                       "isovalue");
}

TEST(TrajectoryCsv, IsovaluesRoundTrip) {
  std::vector<TrajectorySample> samples;
  samples.push_back({0.0, Pose::Identity(), std::numeric_limits<double>::quiet_NaN()});
  samples.push_back({0.5, Pose::Identity(), 0.1 + 0.2});
  const Trajectory original(samples);
  const std::filesystem::path path = test::scratchDir() / "iso.csv";
  writeTrajectoryCsv(original, path);
  const Trajectory back = loadTrajectoryCsv(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_TRUE(std::isnan(back.samples()[0].isovalue));
  EXPECT_EQ(back.samples()[1].isovalue, 0.1 + 0.2);  // bit for bit
}

TEST(TrajectoryCsv, WriteReadRoundTripIsExact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<TrajectorySample> samples;
  for (int i = 0; i < 50; ++i) {
    TrajectorySample s;
    s.t_s = 0.01 * i + 1e-7 * u(rng);
    s.X_WD.p_AB_m = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.1;
    s.X_WD.R_AB = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    samples.push_back(s);
  }
  const Trajectory original(samples);
  const fs::path file = test::scratchDir() / "round-trip.csv";
  writeTrajectoryCsv(original, file);
  const Trajectory read = loadTrajectoryCsv(file);
  ASSERT_EQ(read.size(), original.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read.samples()[i].t_s, original.samples()[i].t_s);
    EXPECT_EQ(read.samples()[i].X_WD.p_AB_m, original.samples()[i].X_WD.p_AB_m);
    EXPECT_NEAR(read.samples()[i].X_WD.R_AB.angularDistance(original.samples()[i].X_WD.R_AB), 0.0, 1e-15);
  }
}

TEST(TrajectoryInterpolation, LerpPositionSlerpRotationAndClamp) {
  const Trajectory t({{1.0, Pose{aboutZ(0.0), {0, 0, 0}}}, {3.0, Pose{aboutZ(M_PI / 2), {0.2, -0.4, 0.02}}}});
  const Pose mid = t.poseAt(2.0);
  EXPECT_TRUE(mid.p_AB_m.isApprox(Eigen::Vector3d(0.1, -0.2, 0.01)));
  EXPECT_NEAR(mid.R_AB.angularDistance(aboutZ(M_PI / 4)), 0.0, 1e-12);
  const Pose quarter = t.poseAt(1.5);
  EXPECT_TRUE(quarter.p_AB_m.isApprox(Eigen::Vector3d(0.05, -0.1, 0.005)));
  EXPECT_NEAR(quarter.R_AB.angularDistance(aboutZ(M_PI / 8)), 0.0, 1e-12);  // constant angular rate
  EXPECT_EQ(t.poseAt(0.0).p_AB_m, t.samples().front().X_WD.p_AB_m);
  EXPECT_EQ(t.poseAt(99.0).p_AB_m, t.samples().back().X_WD.p_AB_m);
  EXPECT_EQ(t.poseAt(std::nan("")).p_AB_m, t.samples().front().X_WD.p_AB_m);
}

TEST(TrajectoryInterpolation, SlerpTakesTheShortestArc) {
  // q and -q are the same rotation: the interpolation must not swing through 2 pi.
  const Eigen::Quaterniond q = aboutZ(0.3);
  const Eigen::Quaterniond minus_q(-q.w(), -q.x(), -q.y(), -q.z());
  const Trajectory t({{0.0, Pose{q, {0, 0, 0}}}, {1.0, Pose{minus_q, {0, 0, 0}}}});
  for (double s : {0.25, 0.5, 0.75}) EXPECT_NEAR(t.poseAt(s).R_AB.angularDistance(q), 0.0, 1e-9) << s;
}

TEST(TrajectoryInterpolation, CursorMatchesBinarySearch) {
  std::vector<TrajectorySample> samples;
  for (int i = 0; i < 40; ++i) {
    samples.push_back({0.1 * i + 0.03 * (i % 3), Pose{aboutZ(0.05 * i), Eigen::Vector3d(std::sin(i), i * 0.01, 0)}});
  }
  const Trajectory t(samples);
  std::size_t cursor = 0;
  for (double time = -0.5; time < 5.0; time += 0.0137) {  // monotonic
    const Pose a = t.poseAt(time, cursor), b = t.poseAt(time);
    ASSERT_TRUE(a.p_AB_m.isApprox(b.p_AB_m, 1e-14) || (a.p_AB_m - b.p_AB_m).norm() < 1e-15) << time;
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 5.0);
  for (int i = 0; i < 500; ++i) {  // random order
    const double time = u(rng);
    const Pose a = t.poseAt(time, cursor), b = t.poseAt(time);
    ASSERT_LT((a.p_AB_m - b.p_AB_m).norm(), 1e-14) << time;
    ASSERT_LT(a.R_AB.angularDistance(b.R_AB), 1e-12) << time;
  }
}

TEST(TrajectoryInterpolation, RejectsBadSamples) {
  VH_EXPECT_THROW_WITH(Trajectory(std::vector<TrajectorySample>{}), std::invalid_argument, "no samples");
  VH_EXPECT_THROW_WITH(Trajectory({{1.0, Pose{}}, {1.0, Pose{}}}), std::invalid_argument, "sample 1", "does not increase");
}

TEST(ScriptedDevice, StepsThroughTheTrajectoryOnePeriodPerRead) {
  // x = t - 2 s over [2, 2.0095] s.
  const Trajectory t({{2.0, Pose::FromTranslation({0, 0, 0})}, {2.0095, Pose::FromTranslation({0.0095, 0, 0})}});
  ScriptedDevice device(t, 1e-3, "t.csv");
  EXPECT_NE(device.name().find("t.csv"), std::string::npos);
  DeviceSample sample;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(device.read(sample));
    EXPECT_FALSE(device.finished()) << i;
    EXPECT_TRUE(sample.valid);
    EXPECT_NEAR(sample.time_s, 2.0 + 1e-3 * i, 1e-12);
    EXPECT_NEAR(sample.X_WD.p_AB_m.x(), 1e-3 * i, 1e-12);
  }
  ASSERT_TRUE(device.read(sample));  // t = 2.010 s: past the end, holds the last pose
  EXPECT_TRUE(device.finished());
  EXPECT_NEAR(sample.X_WD.p_AB_m.x(), 0.0095, 1e-15);
  EXPECT_EQ(device.reads(), 11u);

  DeviceCommand command;
  EXPECT_FALSE(device.lastCommand(command));
  device.command({1, 2, 3}, {4, 5, 6});
  ASSERT_TRUE(device.lastCommand(command));
  EXPECT_EQ(command.force_W_N, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(command.torque_W_Nm, Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(command.count, 1u);
  EXPECT_THROW(ScriptedDevice(Trajectory{}, 1e-3), std::invalid_argument);
  EXPECT_THROW(ScriptedDevice(t, 0.0), std::invalid_argument);
}

TEST(PushSlide, MeetsAnAnalyticPlaneWhereExpected) {
  // Plane z < 0 inside; a ball tool of 5 mm radius: the first contact is where the lowest shell
  // point reaches z = 0.
  const haptics::ScalarVolume plane = datasets::makeBuiltinVolume("plane");
  haptics::PointShellOptions options;
  options.spacing_m = 0.001;
  const haptics::PointShell shell = haptics::makePointShell(datasets::makeBuiltinTool("sphere"), options);
  double lowest = 0.0;
  for (const auto& p : shell.points_T_m()) lowest = std::min(lowest, p.z());
  const Pose start = Pose::FromTranslation({0.002, -0.003, 0.020});
  PushSlideOptions push;
  const PushSlidePlan plan = makePushSlideTrajectory(plane, shell, 0.0, start, push);
  const double expected = 0.020 + lowest;  // travel until the lowest point touches z = 0
  EXPECT_NEAR(plan.contact_distance_m, expected, plane.featureSize_m() / 8 + 1e-9);
  EXPECT_LE(plan.contact_distance_m, expected + 1e-12);  // on the free side
  EXPECT_EQ(countPointsInside(plane, shell, plan.X_WD_contact, 0.0), 0);

  const Trajectory& t = plan.trajectory;
  const Eigen::Vector3d c = plan.X_WD_contact.p_AB_m;
  EXPECT_DOUBLE_EQ(t.startTime_s(), 0.0);
  EXPECT_TRUE(t.poseAt(0.0).p_AB_m.isApprox(c + Eigen::Vector3d(0, 0, push.start_clearance_m)));
  const double t_contact = push.hold_s + push.approach_time_s;
  const double t_deep = t_contact + push.push_time_s;
  const double t_slid = t_deep + push.slide_time_s;
  EXPECT_TRUE(t.poseAt(t_contact).p_AB_m.isApprox(c));
  EXPECT_TRUE(t.poseAt(t_deep).p_AB_m.isApprox(c - Eigen::Vector3d(0, 0, push.push_depth_m)));
  // The default slide is along the W axis most perpendicular to the approach (x here).
  EXPECT_TRUE(t.poseAt(t_slid).p_AB_m.isApprox(c + Eigen::Vector3d(push.slide_m, 0, -push.push_depth_m)));
  EXPECT_NEAR(t.duration_s(), t_slid + 2 * push.hold_s + push.retract_time_s, 1e-12);
  EXPECT_TRUE(t.samples().back().X_WD.p_AB_m.isApprox(c + Eigen::Vector3d(push.slide_m, 0, push.start_clearance_m)));
}

TEST(PushSlide, FailsClearlyWhenTheRayMissesOrStartsInside) {
  const haptics::ScalarVolume plane = datasets::makeBuiltinVolume("plane");
  haptics::PointShellOptions options;
  options.spacing_m = 0.002;
  const haptics::PointShell shell = haptics::makePointShell(datasets::makeBuiltinTool("sphere"), options);
  PushSlideOptions up;
  up.approach_dir_W = Eigen::Vector3d::UnitZ();
  VH_EXPECT_THROW_WITH(makePushSlideTrajectory(plane, shell, 0.0, Pose::FromTranslation({0, 0, 0.02}), up),
                       std::runtime_error, "no surface at isovalue 0");
  VH_EXPECT_THROW_WITH(makePushSlideTrajectory(plane, shell, 0.0, Pose::FromTranslation({0, 0, -0.01})),
                       std::runtime_error, "not free");
}

}  // namespace
}  // namespace vh::runtime
