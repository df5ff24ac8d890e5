// The one LPS <-> RAS conversion (vh/io/patient_frames.h): the named axes flip, the matrix and
// the vector forms agree, and each is its own inverse.

#include <gtest/gtest.h>

#include "vh/io/patient_frames.h"

namespace vh::io::test {
namespace {

TEST(PatientFrames, LeftPosteriorIsRightAnteriorNegated) {
  // The patient's left (+x LPS) is -x in RAS; posterior (+y LPS) is -y; superior stays +z.
  EXPECT_EQ(rasFromLps({1.0, 0.0, 0.0}), Eigen::Vector3d(-1.0, 0.0, 0.0));
  EXPECT_EQ(rasFromLps({0.0, 1.0, 0.0}), Eigen::Vector3d(0.0, -1.0, 0.0));
  EXPECT_EQ(rasFromLps({0.0, 0.0, 1.0}), Eigen::Vector3d(0.0, 0.0, 1.0));
  EXPECT_EQ(lpsFromRas({12.5, -3.0, 40.0}), Eigen::Vector3d(-12.5, 3.0, 40.0));
}

TEST(PatientFrames, MatrixAndVectorFormsAgreeAndInvertThemselves) {
  const Eigen::Vector3d p_LPS(0.1, -0.2, 0.3);
  EXPECT_EQ(rasFromLpsMatrix() * p_LPS, rasFromLps(p_LPS));
  EXPECT_EQ(lpsFromRasMatrix() * rasFromLps(p_LPS), p_LPS);
  EXPECT_EQ(lpsFromRas(rasFromLps(p_LPS)), p_LPS);
  EXPECT_EQ(rasFromLpsMatrix() * lpsFromRasMatrix(), Eigen::Matrix3d::Identity());
  EXPECT_EQ(lpsFromLasMatrix() * lpsFromLasMatrix(), Eigen::Matrix3d::Identity());
  EXPECT_EQ(lpsFromLasMatrix() * Eigen::Vector3d(1.0, 2.0, 3.0), Eigen::Vector3d(1.0, -2.0, 3.0));
}

}  // namespace
}  // namespace vh::io::test
