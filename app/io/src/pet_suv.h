#pragma once
/// @file
/// PET values in SUV (body weight): the factor from a PET series' header. Private to vh::io.
///
/// Sources: the QIBA / Uniform Protocols for Imaging in Medicine "Vendor-neutral pseudo-code for
/// SUV calculation" (QIBA FDG-PET/CT profile) and DICOM PS3.3 C.8.9.1 (PET Series module:
/// Units (0054,1001), Decay Correction (0054,1102)) and C.8.9.2 (PET Isotope module: the
/// Radiopharmaceutical Information Sequence (0054,0016)).

#include <string>

class vtkDICOMMetaData;

namespace vh::io::detail {

/// What a PET series' header says about its values in SUV.
struct PetSuv {
  /// The values become SUVbw: data values [Bq/ml] (after RescaleSlope / RescaleIntercept)
  /// times `factor`.
  bool in_suv = false;
  /// SUVbw per Bq/ml [g/Bq]: PatientWeight [kg] * 1000 [g/kg] / the injected dose [Bq] decayed
  /// to the time the images are decay-corrected to; 1 for Units GML (stored in SUV already).
  double factor = 1.0;
  /// The values' unit: "SUVbw", "Bq/ml" (Units BQML that cannot become SUV), or "" (other Units).
  std::string unit;
  /// One sentence for VolumeInfo::notices: the factor and what it came from, or which attribute
  /// is missing or unusable.
  std::string notice;
};

/// SUVbw of a PET series (Modality PT) from its header: instance 0 of `md` for Units,
/// DecayCorrection, PatientWeight and item 0 of the RadiopharmaceuticalInformationSequence
/// (RadionuclideTotalDose [Bq], RadionuclideHalfLife [s], RadiopharmaceuticalStartDateTime or
/// RadiopharmaceuticalStartTime); every instance for the earliest AcquisitionDate / Time.
/// Decay correction START: the dose decays from the injection to SeriesDate / SeriesTime, or to
/// the earliest acquisition when the series time is after it (a series created by
/// post-processing), as the QIBA pseudo-code says; ADMIN: no decay (the images are corrected to
/// the administration); NONE: as START to the earliest acquisition, with the error of later
/// slices in the notice (each slice would need its own factor). An injection the day before the
/// scan (times without dates, the scan's time of day earlier) crosses midnight.
/// Never throws: a missing or unusable attribute gives in_suv = false and a notice naming it.
PetSuv petSuv(vtkDICOMMetaData* md) noexcept;

}  // namespace vh::io::detail
