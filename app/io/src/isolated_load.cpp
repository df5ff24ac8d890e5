// Loading in the reader process (vh/io/reader_process.h): loadMesh(), listDicomSeries(), the
// DICOM SEG and RT Structure Set reads and the DICOM, NRRD and MetaImage loads start the reader
// program, pass the request on its command line, take the result back from its output file and
// name the damaged file when a reader crashes or stalls. Without the reader program they read in this process.
//
// Why: vtk-dicom's parser has crashed (SIGSEGV in vtkDICOMParser::ReadMetaData) on damaged
// files, and VTK's NRRD, MetaImage, OBJ and PLY readers crash or hang on some
// (tests/fuzz/known-crashes); DCMTK's dcmseg reads whole multi-frame files that may be as
// damaged; in the reader process such a crash ends that process, and the
// application names the file and keeps what it had open. After a DICOM reader's crash the
// reader's `probe` mode parses the files one by one: the last one named is the damaged file;
// when every file parses alone, the series read is repeated on halves of the files
// (findSeriesCulprits()) until the damaged slice among good ones is found.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "dicom_rtstruct_internal.h"
#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "reader_process_internal.h"
#include "reader_transfer.h"
#include "vh/io/dicom_series.h"
#include "vh/io/reader_process.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;

/// The reader program, or empty when `isolation` asks for this process.
fs::path readerFor(DicomIsolation isolation) {
  return isolation == DicomIsolation::kInProcess ? fs::path() : readerProcessPath();
}

/// The LoadError text for a DICOM reader that crashed or stalled (`what`): names the files the
/// probe stops on (findCulpritFiles()), else `doing` ("reading the series"), then
/// `consequence`; with files named, how to open the series without them (the folder is scanned
/// with its sub-folders, so the files must leave the folder). One file: "... on PATH: a damaged
/// file..."; several: "... on N damaged files: PATH | PATH | PATH..." (damagedFilesNamed() in
/// the window reads them back).
std::string dicomReaderProblem(const std::string& what, const std::vector<std::string>& culprits, const char* doing,
                               const char* consequence) {
  if (culprits.empty()) return "the DICOM reader " + what + " " + doing + ": a damaged file" + consequence;
  if (culprits.size() == 1) {
    return "the DICOM reader " + what + " on " + culprits[0] + ": a damaged file" + consequence +
           ". To open the series without it, move " + fs::path(culprits[0]).filename().string() +
           " out of the folder (and its sub-folders) and open the folder again";
  }
  std::string paths, names;
  for (std::size_t i = 0; i < culprits.size(); ++i) {
    paths += (i == 0 ? "" : " | ") + culprits[i];
    names += (i == 0 ? "" : i + 1 == culprits.size() ? " and " : ", ") + fs::path(culprits[i]).filename().string();
  }
  return "the DICOM reader " + what + " on " + std::to_string(culprits.size()) + " damaged files: " + paths +
         consequence + ". To open the series without them, move " + names +
         " out of the folder (and its sub-folders) and open the folder again";
}

}  // namespace

haptics::TriangleMesh loadMesh(const fs::path& path, double scale_to_m) {
  const fs::path reader = readerProcessPath();
  if (reader.empty() || !(scale_to_m > 0.0) || !std::isfinite(scale_to_m)) {
    return detail::loadMeshInProcess(path, scale_to_m);  // also names a bad scale
  }
  std::error_code ec;
  const detail::ReaderOutputFile out("mesh");
  std::ostringstream scale;
  scale.precision(17);
  scale << scale_to_m;
  detail::runReaderToEnd({reader.string(), "mesh", fs::absolute(path, ec).string(), out.path().string(), scale.str()},
                         path, detail::stallLimitFor(path, detail::kDefaultStallS), {}, nullptr,
                         [](const std::string& what) {
                           return "the mesh reader " + what + ": a damaged file; nothing was loaded";
                         });
  return detail::readMesh(out.path(), path);
}

std::vector<DicomSeriesInfo> listDicomSeries(const fs::path& folder, const std::function<void(int, int)>& progress,
                                             const std::atomic<bool>* cancel) {
  const fs::path reader = readerProcessPath();
  if (reader.empty()) return detail::listDicomSeriesInProcess(folder, progress, cancel);
  std::error_code ec;
  const detail::ReaderOutputFile out("dicom-list");
  const auto on_line = [&](const std::string& line) {
    int done = 0, total = 0;
    if (progress && std::sscanf(line.c_str(), "progress %d %d", &done, &total) == 2) progress(done, total);
  };
  const bool finished = detail::runReaderToEnd(
      {reader.string(), "list", fs::absolute(folder, ec).string(), out.path().string()}, folder,
      detail::kDefaultStallS, on_line, cancel, [&](const std::string& what) {
        return dicomReaderProblem(what, detail::findCulpritFiles(reader, folder, detail::kDefaultStallS),
                                  "listing the folder", "");
      });
  if (!finished) return {};
  return detail::readSeriesList(out.path(), folder);
}

namespace detail {

LoadedVolume loadFileIsolated(const fs::path& path, const VolumeLoadOptions& options,
                              const std::function<LoadedVolume()>& in_process) {
  const fs::path reader = readerFor(options.dicom_isolation);
  if (reader.empty()) {
    if (options.dicom_isolation == DicomIsolation::kWorker) {
      fail(path, std::string("the reader program (") + kReaderProgramName + ") was not found");
    }
    return in_process();
  }
  std::error_code ec;
  const ReaderOutputFile out("volume");
  std::vector<std::string> args = {reader.string(), "volume", fs::absolute(path, ec).string(), out.path().string()};
  if (options.nrrd_layer != 0) args.insert(args.end(), {"--layer", std::to_string(options.nrrd_layer)});
  const bool finished = runReaderToEnd(args, path, stallLimitFor(path, options.worker_stall_timeout_s), {},
                                       options.cancel, [](const std::string& what) {
                                         return "the volume reader " + what + ": a damaged file; nothing was loaded";
                                       });
  if (!finished) throw LoadCancelled(path.string() + ": loading cancelled");
  return readField(out.path(), path);
}

DicomSegFile readDicomSeg(const fs::path& path, const VolumeLoadOptions& options) {
  const fs::path reader = readerFor(options.dicom_isolation);
  if (reader.empty()) {
    if (options.dicom_isolation == DicomIsolation::kWorker) {
      fail(path, std::string("the reader program (") + kReaderProgramName + ") was not found");
    }
    DicomSegFile seg = readDicomSegInProcess(path);
    if (options.dicom_isolation == DicomIsolation::kAuto) {
      seg.notices.push_back(std::string("read in this process: the reader program (") + kReaderProgramName +
                            ") was not found, so a damaged file could end the program");
    }
    return seg;
  }
  std::error_code ec;
  const ReaderOutputFile out("dicom-seg");
  const bool finished = runReaderToEnd({reader.string(), "seg", fs::absolute(path, ec).string(), out.path().string()},
                                       path, stallLimitFor(path, options.worker_stall_timeout_s), {}, options.cancel,
                                       [](const std::string& what) {
                                         return "the DICOM SEG reader " + what + ": a damaged file; nothing was loaded";
                                       });
  if (!finished) throw LoadCancelled(path.string() + ": loading cancelled");
  return readDicomSegTransfer(out.path(), path);
}

RtStructFile readDicomRtStruct(const fs::path& path, const VolumeLoadOptions& options) {
  const fs::path reader = readerFor(options.dicom_isolation);
  if (reader.empty()) {
    if (options.dicom_isolation == DicomIsolation::kWorker) {
      fail(path, std::string("the reader program (") + kReaderProgramName + ") was not found");
    }
    RtStructFile rs = readDicomRtStructInProcess(path);
    if (options.dicom_isolation == DicomIsolation::kAuto) {
      rs.notices.push_back(std::string("read in this process: the reader program (") + kReaderProgramName +
                           ") was not found, so a damaged file could end the program");
    }
    return rs;
  }
  std::error_code ec;
  const ReaderOutputFile out("dicom-rtstruct");
  const bool finished =
      runReaderToEnd({reader.string(), "rtstruct", fs::absolute(path, ec).string(), out.path().string()}, path,
                     stallLimitFor(path, options.worker_stall_timeout_s), {}, options.cancel,
                     [](const std::string& what) {
                       return "the RT Structure Set reader " + what + ": a damaged file; nothing was loaded";
                     });
  if (!finished) throw LoadCancelled(path.string() + ": loading cancelled");
  return readDicomRtStructTransfer(out.path(), path);
}

LoadedVolume loadDicom(const fs::path& path, const VolumeLoadOptions& options) {
  const fs::path reader = readerFor(options.dicom_isolation);
  if (reader.empty()) {
    if (options.dicom_isolation == DicomIsolation::kWorker) {
      fail(path, std::string("the reader program (") + kReaderProgramName + ") was not found");
    }
    RawVolume raw = loadDicomRaw(path, options);
    if (options.dicom_isolation == DicomIsolation::kAuto) {
      raw.info.notices.push_back(std::string("read in this process: the reader program (") + kReaderProgramName +
                                 ") was not found, so a damaged file could end the program");
    }
    return finishVolume(std::move(raw), path);
  }
  std::error_code ec;
  const ReaderOutputFile out("dicom");
  std::vector<std::string> args = {reader.string(), "load", fs::absolute(path, ec).string(), out.path().string()};
  if (!options.dicom_series.empty()) args.insert(args.end(), {"--series", options.dicom_series});
  if (options.dicom_phase != 0) args.insert(args.end(), {"--phase", std::to_string(options.dicom_phase)});
  // The reader's progress covers 0..0.9; taking the voxels back and converting them the rest.
  const auto on_line = [&](const std::string& line) {
    if (line.rfind("progress ", 0) == 0 && options.progress) options.progress(0.9 * std::strtod(line.c_str() + 9, nullptr));
  };
  const double stall_s = stallLimitFor(path, options.worker_stall_timeout_s);
  const bool finished = runReaderToEnd(args, path, stall_s, on_line, options.cancel, [&](const std::string& what) {
    std::vector<std::string> culprits = findCulpritFiles(reader, path, stall_s);
    // Every file parses alone: the series read itself fails on a damaged slice among good ones.
    std::error_code ec;
    if (culprits.empty() && fs::is_directory(path, ec)) {
      try {
        culprits = findSeriesCulprits(reader, path, std::vector<std::string>(args.begin() + 4, args.end()), stall_s);
      } catch (const LoadError&) {  // NOLINT(bugprone-empty-catch): the crash is said without a file then
      }
    }
    return dicomReaderProblem(what, culprits, "reading the series", "; nothing was loaded");
  });
  if (!finished) throw LoadCancelled(path.string() + ": loading cancelled");
  RawVolume raw = readRaw(out.path(), path);
  if (options.progress) options.progress(0.95);
  return finishVolume(std::move(raw), path);
}

}  // namespace detail
}  // namespace vh::io
