#pragma once
/// @file
/// Listing the DICOM image series of a folder (vtkDICOMDirectory) so a user can choose one, and
/// loading the chosen series. A folder exported from a scanner often holds several series
/// (scout, soft-tissue and bone reconstructions, contrast phases); loadVolume() picks the
/// largest, these functions let the GUI ask.

#include <atomic>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "vh/io/volume_loader.h"

namespace vh::io {

/// What a series chooser shows of one series. Text fields are UTF-8, empty when absent.
struct DicomSeriesInfo {
  std::filesystem::path folder;      ///< The folder that was scanned.
  int index = -1;                    ///< Series index in the scan of `folder` (0-based).
  std::string patient_name;          ///< (0010,0010), DICOM "^" separators kept.
  std::string patient_id;            ///< (0010,0020).
  std::string study_description;     ///< (0008,1030).
  std::string study_date;            ///< (0008,0020), YYYYMMDD.
  std::string series_description;    ///< (0008,103E).
  std::string series_uid;            ///< (0020,000E).
  int series_number = 0;             ///< (0020,0011), 0 when absent.
  std::string modality;              ///< (0008,0060), e.g. "CT", "MR".
  int file_count = 0;                ///< Image files in the series.
  int slice_count = 0;               ///< Slices of the volume the series makes (frames of one
                                     ///< time point; equals file_count for 2-D files).
  int rows = 0;                      ///< Image rows (voxels along j).
  int columns = 0;                   ///< Image columns (voxels along i).
  /// Voxel size [mm] along the image's i (column), j (row) and slice directions; the slice
  /// spacing comes from the sorted slice positions (0 when a single slice).
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Zero();
  std::vector<std::filesystem::path> files;  ///< The series' image files (scan order).
};

/// Lists the image series under `folder` (the folder and its sub-folders, two levels deep;
/// a DICOMDIR is ignored: the files themselves are scanned; files without pixel data are
/// skipped). Series are in the scanner's patient / study / series order.
/// @param progress when set, called with (series done, series total) while each series' slice
///        geometry is read; may be called from the calling thread only.
/// @param cancel when set and it becomes true, the listing stops early and returns what it has.
/// Runs in the reader process when it is found (reader_process.h): a parser crash on a
/// damaged file becomes a LoadError naming it.
/// @throws LoadError naming the folder: missing, not a folder, or no DICOM image series in it;
///         a crash of the reader on a damaged file.
/// May be called from any thread.
std::vector<DicomSeriesInfo> listDicomSeries(
    const std::filesystem::path& folder,
    const std::function<void(int done, int total)>& progress = {},
    const std::atomic<bool>* cancel = nullptr);

/// Loads series `series_index` (as numbered by listDicomSeries()) of `folder`, with the same
/// geometry, units and checks as loadVolume() (W = patient LPS in metres; values in HU for CT).
/// @throws LoadError naming the folder for an index out of range or no series, or naming the
///         file and problem as loadVolume().
LoadedVolume loadDicomSeries(const std::filesystem::path& folder, int series_index);

/// Loads a series already listed by listDicomSeries() (no second scan of the folder).
/// @throws LoadError as loadVolume(); for a series without files.
LoadedVolume loadDicomSeries(const DicomSeriesInfo& series);

}  // namespace vh::io
