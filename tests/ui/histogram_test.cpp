// Histogram of a volume's values (ui/histogram.h): bins, range, totals, VTK scalar types.
#include "vh/ui/panels/histogram.h"

#include <atomic>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkShortArray.h>

namespace vh::ui {
namespace {

TEST(Histogram, CountsValuesIntoEqualBins) {
  const Histogram h = computeHistogram(std::vector<double>{0, 1, 2, 3, 4, 5, 6, 7, 8, 10}, 5);
  ASSERT_EQ(h.binCount(), 5);
  EXPECT_DOUBLE_EQ(h.min_value, 0.0);
  EXPECT_DOUBLE_EQ(h.max_value, 10.0);
  EXPECT_DOUBLE_EQ(h.binWidth(), 2.0);
  // [0,2) [2,4) [4,6) [6,8) [8,10]: the maximum goes into the last bin.
  EXPECT_EQ(h.counts, (std::vector<std::uint64_t>{2, 2, 2, 2, 2}));
  EXPECT_EQ(h.total(), 10u);
  EXPECT_EQ(h.binOf(-5.0), 0);
  EXPECT_EQ(h.binOf(5.0), 2);
  EXPECT_EQ(h.binOf(99.0), 4);
  EXPECT_DOUBLE_EQ(h.binCentre(0), 1.0);
}

TEST(Histogram, SkipsNonFiniteValuesAndHandlesConstants) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Histogram h = computeHistogram(std::vector<double>{nan, 3.0, 3.0, INFINITY}, 4);
  EXPECT_EQ(h.total(), 2u);
  EXPECT_DOUBLE_EQ(h.min_value, 3.0);
  EXPECT_DOUBLE_EQ(h.max_value, 4.0) << "a constant array gets one unit of width";
  EXPECT_TRUE(computeHistogram(std::vector<double>{}, 4).empty());
  EXPECT_TRUE(computeHistogram(std::vector<double>{1.0}, 0).empty());
}

TEST(Histogram, ReadsImageScalarsOfAnyType) {
  vtkNew<vtkImageData> image;
  image->SetDimensions(10, 10, 10);
  vtkNew<vtkShortArray> values;
  values->SetNumberOfTuples(1000);
  for (vtkIdType i = 0; i < 1000; ++i) values->SetValue(i, static_cast<short>(i < 900 ? -1000 : 1000));  // air, bone
  image->GetPointData()->SetScalars(values);
  const Histogram h = computeHistogram(image, 256);
  ASSERT_EQ(h.binCount(), 256);
  EXPECT_EQ(h.total(), 1000u);
  EXPECT_DOUBLE_EQ(h.min_value, -1000.0);
  EXPECT_DOUBLE_EQ(h.max_value, 1000.0);
  EXPECT_EQ(h.counts.front(), 900u);
  EXPECT_EQ(h.counts.back(), 100u);

  vtkNew<vtkFloatArray> floats;
  floats->SetNumberOfTuples(1000);
  for (vtkIdType i = 0; i < 1000; ++i) floats->SetValue(i, static_cast<float>(i) * 0.001f);
  image->GetPointData()->SetScalars(floats);
  const Histogram f = computeHistogram(image, 10);
  EXPECT_EQ(f.total(), 1000u);
  for (const auto c : f.counts) EXPECT_NEAR(static_cast<double>(c), 100.0, 1.0);

  EXPECT_TRUE(computeHistogram(nullptr).empty());
  std::atomic<bool> cancel{true};
  EXPECT_TRUE(computeHistogram(image, 10, &cancel).empty()) << "a cancelled computation returns nothing";
}

}  // namespace
}  // namespace vh::ui
