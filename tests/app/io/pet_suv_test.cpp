// PET series open in SUV (body weight): small PET series (8 x 8 x 4, Modality PT, PET Image
// Storage) written by the fixtures with the PET Series and Isotope tags, loaded through
// vh::io::loadVolume(), every voxel compared with SUV computed here by hand from the header
// values written:
//   SUVbw = (RescaleSlope * stored + RescaleIntercept) [Bq/ml] * weight [kg] * 1000 [g/kg]
//           / (dose [Bq] * 2^(-(reference time - injection time) / half-life)),
// the reference time being what DecayCorrection (0054,1102) says the images are corrected to
// (QIBA vendor-neutral SUV pseudo-code; DICOM PS3.3 C.8.9.1).

#include <cmath>
#include <functional>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <vtkDICOMDictHash.h>
#include <vtkDICOMItem.h>
#include <vtkDICOMMetaData.h>
#include <vtkDICOMSequence.h>
#include <vtkDICOMValue.h>
#include <vtkImageData.h>

#include "dicom_fixtures.h"
#include "io_test_support.h"
#include "vh/io/volume_loader.h"

namespace vh::io::test {
namespace {

constexpr int kNx = 8, kNy = 8, kNz = 4;

/// Stored value of source voxel (i, j, k): different in every voxel and slice.
short storedAt(int i, int j, int k) { return static_cast<short>(400 * (k + 1) + 20 * i + 10 * j); }

/// What the PET header of a written series says. Empty strings and null numbers are not written.
struct PetHeader {
  std::string units = "BQML";
  std::string decay_correction = "START";
  std::optional<double> weight_kg = 70.0;
  std::optional<double> dose_bq = 370.0e6;
  std::optional<double> half_life_s = 6586.2;  // F-18
  std::string start_time = "090000";           // RadiopharmaceuticalStartTime
  std::string start_date_time;                 // RadiopharmaceuticalStartDateTime
  std::string series_date = "20240105";
  std::string series_time = "100000";
  std::string acquisition_date = "20240105";
  /// AcquisitionTime of slice k: acquisition_times[min(k, size - 1)].
  std::vector<std::string> acquisition_times = {"100000"};
  /// RescaleSlope of slice k (one value: the same for every file).
  std::function<double(int k)> slope = [](int) { return 2.5; };
  double intercept = 0.0;
};

/// Writes the 8 x 8 x 4 PET series of `h` into `folder` (2 x 2 x 3 mm voxels, axial).
WrittenSeries writePet(const fs::path& folder, const PetHeader& h) {
  SourceVolume src;
  src.image = vtkSmartPointer<vtkImageData>::New();
  src.image->SetDimensions(kNx, kNy, kNz);
  src.image->AllocateScalars(VTK_SHORT, 1);
  for (int k = 0; k < kNz; ++k)
    for (int j = 0; j < kNy; ++j)
      for (int i = 0; i < kNx; ++i) src.image->SetScalarComponentFromDouble(i, j, k, 0, storedAt(i, j, k));
  src.ijk_to_lps_mm.setIdentity();
  src.ijk_to_lps_mm.topLeftCorner<3, 3>() = Eigen::Vector3d(2.0, 2.0, 3.0).asDiagonal();
  SeriesSpec spec;
  spec.modality = "PT";
  spec.series_description = "PET WB";
  spec.instance_tags = [&h](vtkDICOMMetaData* meta, int i, int k) {
    const auto setText = [&](vtkDICOMTag tag, const std::string& value) {
      if (!value.empty()) meta->Set(i, tag, value);
    };
    setText(DC::Units, h.units);
    setText(DC::DecayCorrection, h.decay_correction);
    setText(DC::CorrectedImage, "ATTN\\DECY");
    if (h.weight_kg) meta->Set(i, DC::PatientWeight, *h.weight_kg);
    vtkDICOMItem drug;
    drug.Set(DC::Radiopharmaceutical, "Fluorodeoxyglucose F^18^");
    if (h.dose_bq) drug.Set(DC::RadionuclideTotalDose, *h.dose_bq);
    if (h.half_life_s) drug.Set(DC::RadionuclideHalfLife, *h.half_life_s);
    if (!h.start_time.empty()) drug.Set(DC::RadiopharmaceuticalStartTime, h.start_time);
    if (!h.start_date_time.empty()) drug.Set(DC::RadiopharmaceuticalStartDateTime, h.start_date_time);
    vtkDICOMSequence seq;
    seq.AddItem(drug);
    meta->Set(i, DC::RadiopharmaceuticalInformationSequence, vtkDICOMValue(seq));
    setText(DC::SeriesDate, h.series_date);
    setText(DC::SeriesTime, h.series_time);
    setText(DC::AcquisitionDate, h.acquisition_date);
    const auto& times = h.acquisition_times;
    setText(DC::AcquisitionTime, times[std::min<std::size_t>(static_cast<std::size_t>(k), times.size() - 1)]);
    meta->Set(i, DC::RescaleSlope, h.slope(k));
    meta->Set(i, DC::RescaleIntercept, h.intercept);
  };
  return writeSeries(folder, src, spec);
}

std::string notices(const LoadedVolume& v) {
  std::string out;
  for (const auto& n : v.info.notices) out += "\n  " + n;
  return out;
}

/// The notice starting with "PET" (there is exactly one for a PET series), or "".
std::string petNotice(const LoadedVolume& v) {
  std::string out;
  int count = 0;
  for (const auto& n : v.info.notices) {
    if (n.rfind("PET ", 0) == 0) {
      out = n;
      ++count;
    }
  }
  EXPECT_EQ(count, 1) << notices(v);
  return out;
}

/// Every voxel of the loaded field and of its rendering image against `expected(i, j, k)`, to
/// 1e-4 relative; the field's value range too (the isovalue range and default come from it).
void expectValues(const LoadedVolume& v, const std::function<double(int, int, int)>& expected) {
  ASSERT_NE(v.field, nullptr);
  ASSERT_NE(v.image, nullptr);
  const auto& g = v.field->geometry();
  ASSERT_EQ(g.dims, (std::array<int, 3>{kNx, kNy, kNz}));
  EXPECT_LT((g.direction_W - Eigen::Matrix3d::Identity()).norm(), 1e-9);
  double worst = 0.0, lo = INFINITY, hi = -INFINITY;
  std::string where;
  for (int k = 0; k < kNz; ++k)
    for (int j = 0; j < kNy; ++j)
      for (int i = 0; i < kNx; ++i) {
        const double want = expected(i, j, k);
        lo = std::min(lo, want);
        hi = std::max(hi, want);
        for (const double got : {v.field->voxel(i, j, k), v.image->GetScalarComponentAsDouble(i, j, k, 0)}) {
          const double rel = std::abs(got - want) / std::abs(want);
          if (!(rel <= worst)) {
            worst = rel;
            where = "voxel (" + std::to_string(i) + ", " + std::to_string(j) + ", " + std::to_string(k) + "): " +
                    std::to_string(got) + " where " + std::to_string(want) + " was expected";
          }
        }
      }
  EXPECT_LT(worst, 1e-4) << where;
  EXPECT_NEAR(v.field->minValue(), lo, 1e-4 * std::abs(lo));
  EXPECT_NEAR(v.field->maxValue(), hi, 1e-4 * std::abs(hi));
}

class PetSuv : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::make_unique<TempDir>(testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  /// Writes `h` into a folder of its own and loads it (through the reader process when
  /// `isolation` says so, as the application does).
  LoadedVolume load(const std::string& name, const PetHeader& h, DicomIsolation isolation = DicomIsolation::kAuto) {
    writePet(dir_->path() / name, h);
    VolumeLoadOptions options;
    options.dicom_isolation = isolation;
    LoadedVolume v = loadVolume(dir_->path() / name, options);
    std::cout << "[pet] " << name << ": unit '" << v.info.value_unit << "'" << notices(v) << "\n";
    return v;
  }
  std::unique_ptr<TempDir> dir_;
};

/// Bq/ml of voxel (i, j, k) with RescaleSlope 2.5.
double bqml(int i, int j, int k) { return 2.5 * storedAt(i, j, k); }

TEST_F(PetSuv, StartDecayCorrectionDecaysTheDoseToTheSeriesTime) {
  // 70 kg, 370 MBq of F-18 (half-life 6586.2 s) injected at 09:00:00, series at 10:00:00.
  const double factor = 70.0 * 1000.0 / (370.0e6 * std::pow(2.0, -3600.0 / 6586.2));
  for (const DicomIsolation isolation : {DicomIsolation::kAuto, DicomIsolation::kInProcess}) {
    const LoadedVolume v = load(isolation == DicomIsolation::kAuto ? "worker" : "in_process", PetHeader{}, isolation);
    EXPECT_EQ(v.info.modality, "PT");
    EXPECT_EQ(v.info.value_unit, "SUVbw");
    expectValues(v, [&](int i, int j, int k) { return bqml(i, j, k) * factor; });
    EXPECT_EQ(petNotice(v),
              "PET in SUV (body weight): weight 70 kg, injected dose 370 MBq at 09:00:00, decay-corrected to "
              "10:00:00 (DecayCorrection START), factor 0.0002763");
  }
  EXPECT_NEAR(factor, 2.763e-4, 1e-7);  // the notice's factor, written out
}

TEST_F(PetSuv, StartUsesTheEarliestAcquisitionWhenTheSeriesTimeIsLater) {
  // A series written after the scan (SeriesTime 11:30): the images are corrected to the first
  // acquisition, 10:00:00 (slices at 10:00:00 .. 10:03:00).
  PetHeader h;
  h.series_time = "113000";
  h.acquisition_times = {"100300", "100000", "100100", "100200"};
  const LoadedVolume v = load("post_processed", h);
  const double factor = 70.0 * 1000.0 / (370.0e6 * std::pow(2.0, -3600.0 / 6586.2));
  EXPECT_EQ(v.info.value_unit, "SUVbw");
  expectValues(v, [&](int i, int j, int k) { return bqml(i, j, k) * factor; });
  EXPECT_NE(petNotice(v).find("decay-corrected to 10:00:00 (DecayCorrection START)"), std::string::npos);
}

TEST_F(PetSuv, TimesInOtherSpellingsGiveTheSameFactor) {
  // TM without seconds, ACR-NEMA's colons and a fraction: still 09:00 to 10:00.
  PetHeader h;
  h.start_time = "0900";
  h.series_time = "10:00:00.000000";
  h.acquisition_times = {"100000.5"};
  const LoadedVolume v = load("spellings", h);
  const double factor = 70.0 * 1000.0 / (370.0e6 * std::pow(2.0, -3600.0 / 6586.2));
  EXPECT_EQ(v.info.value_unit, "SUVbw");
  expectValues(v, [&](int i, int j, int k) { return bqml(i, j, k) * factor; });
}

TEST_F(PetSuv, PerSliceRescaleSlopesAreAppliedBeforeTheFactor) {
  // GE writes a RescaleSlope per slice; vtk-dicom rescales each slice, then the factor applies.
  PetHeader h;
  h.slope = [](int k) { return 1.5 + 0.25 * k; };
  h.intercept = 0.0;
  const LoadedVolume v = load("slopes", h);
  const double factor = 70.0 * 1000.0 / (370.0e6 * std::pow(2.0, -3600.0 / 6586.2));
  EXPECT_EQ(v.info.value_unit, "SUVbw");
  expectValues(v, [&](int i, int j, int k) { return (1.5 + 0.25 * k) * storedAt(i, j, k) * factor; });
}

TEST_F(PetSuv, AdminDecayCorrectionUsesTheDoseAsInjected) {
  PetHeader h;
  h.decay_correction = "ADMIN";
  const LoadedVolume v = load("admin", h);
  const double factor = 70.0 * 1000.0 / 370.0e6;
  EXPECT_EQ(v.info.value_unit, "SUVbw");
  expectValues(v, [&](int i, int j, int k) { return bqml(i, j, k) * factor; });
  EXPECT_EQ(petNotice(v),
            "PET in SUV (body weight): weight 70 kg, injected dose 370 MBq at 09:00:00, decay-corrected to "
            "09:00:00 (DecayCorrection ADMIN), factor 0.0001892");
}

TEST_F(PetSuv, NoDecayCorrectionUsesTheFirstAcquisitionAndSaysHowFarTheLastIsOff) {
  // Slices at 10:00:00 .. 10:03:00, not decay-corrected: the factor is for 10:00:00, and the
  // last slice's 180 s more of decay are named.
  PetHeader h;
  h.decay_correction = "NONE";
  h.acquisition_times = {"100000", "100100", "100200", "100300"};
  const LoadedVolume v = load("none", h);
  const double factor = 70.0 * 1000.0 / (370.0e6 * std::pow(2.0, -3600.0 / 6586.2));
  EXPECT_EQ(v.info.value_unit, "SUVbw");
  expectValues(v, [&](int i, int j, int k) { return bqml(i, j, k) * factor; });
  const std::string notice = petNotice(v);
  EXPECT_NE(notice.find("decay-corrected to 10:00:00 (DecayCorrection NONE)"), std::string::npos) << notice;
  const double low_percent = 100.0 * (1.0 - std::pow(2.0, -180.0 / 6586.2));  // 1.877 %
  EXPECT_NE(notice.find("the last reads 1.877 % low"), std::string::npos) << notice << " (" << low_percent << ")";
}

TEST_F(PetSuv, InjectionBeforeMidnightAndScanAfterIsOneHour) {
  // Injected at 23:30:00 on 5 January, scanned at 00:30:00 on 6 January: 3600 s of decay, with
  // the injection's time alone (RadiopharmaceuticalStartTime) and with its date and time.
  const double factor = 70.0 * 1000.0 / (370.0e6 * std::pow(2.0, -3600.0 / 6586.2));
  for (const bool with_date : {false, true}) {
    PetHeader h;
    h.start_time = with_date ? "" : "233000";
    h.start_date_time = with_date ? "20240105233000.00" : "";
    h.series_date = h.acquisition_date = "20240106";
    h.series_time = "003000";
    h.acquisition_times = {"003000"};
    const LoadedVolume v = load(with_date ? "midnight_date" : "midnight_time", h);
    EXPECT_EQ(v.info.value_unit, "SUVbw");
    expectValues(v, [&](int i, int j, int k) { return bqml(i, j, k) * factor; });
    EXPECT_EQ(petNotice(v),
              "PET in SUV (body weight): weight 70 kg, injected dose 370 MBq at 23:30:00, decay-corrected to "
              "00:30:00 (DecayCorrection START), factor 0.0002763");
  }
}

TEST_F(PetSuv, UnitsGmlAreSuvAlready) {
  PetHeader h;
  h.units = "GML";
  h.slope = [](int) { return 0.001; };
  const LoadedVolume v = load("gml", h);
  EXPECT_EQ(v.info.value_unit, "SUVbw");
  expectValues(v, [&](int i, int j, int k) { return 0.001 * storedAt(i, j, k); });
  EXPECT_EQ(petNotice(v), "PET in SUV (body weight) as stored (Units GML)");
}

TEST_F(PetSuv, AMissingOrZeroAttributeLeavesBqPerMlAndNamesIt) {
  struct Case {
    std::string name;
    std::function<void(PetHeader&)> change;
    std::string why;
  };
  const std::vector<Case> cases = {
      {"no_weight", [](PetHeader& h) { h.weight_kg.reset(); }, "PatientWeight is missing"},
      {"zero_weight", [](PetHeader& h) { h.weight_kg = 0.0; }, "PatientWeight is 0 kg"},
      {"no_dose", [](PetHeader& h) { h.dose_bq.reset(); }, "RadionuclideTotalDose is missing"},
      {"no_half_life", [](PetHeader& h) { h.half_life_s.reset(); }, "RadionuclideHalfLife is missing"},
      {"zero_half_life", [](PetHeader& h) { h.half_life_s = 0.0; }, "RadionuclideHalfLife is 0 s"},
      {"no_start", [](PetHeader& h) { h.start_time.clear(); }, "RadiopharmaceuticalStartTime is missing"},
      {"no_decay_correction", [](PetHeader& h) { h.decay_correction.clear(); }, "DecayCorrection is missing"},
      {"odd_decay_correction", [](PetHeader& h) { h.decay_correction = "LATER"; },
       "DecayCorrection 'LATER' is not START, ADMIN or NONE"},
      {"injection_after_scan",
       [](PetHeader& h) {
         h.start_time.clear();
         h.start_date_time = "20240105110000";
       },
       "the injection (11:00:00) is after the scan (10:00:00)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    PetHeader h;
    c.change(h);
    const LoadedVolume v = load(c.name, h);
    EXPECT_EQ(v.info.value_unit, "Bq/ml");
    expectValues(v, bqml);
    EXPECT_EQ(petNotice(v), "PET values in Bq/ml, not SUV: " + c.why);
  }
}

TEST_F(PetSuv, CountsStayAsStored) {
  PetHeader h;
  h.units = "CNTS";
  const LoadedVolume v = load("counts", h);
  EXPECT_EQ(v.info.value_unit, "");
  expectValues(v, bqml);
  EXPECT_EQ(petNotice(v), "PET values in CNTS, not SUV: SUV needs Units BQML (Bq/ml)");
}

}  // namespace
}  // namespace vh::io::test
