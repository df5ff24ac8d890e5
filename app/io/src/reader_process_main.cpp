// The reader process's own side: readerProcessMain(), one function per mode. Each reads in this
// process (DicomIsolation::kInProcess), hands the result back through the output file
// (reader_transfer.h) and reports on stdout in the line protocol of reader_process_internal.h.
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include <vtkDICOMMetaData.h>
#include <vtkDICOMParser.h>
#include <vtkSmartPointer.h>

#include "dicom_rtstruct_internal.h"
#include "dicom_seg_internal.h"
#include "loader_internal.h"
#include "pacs_internal.h"
#include "reader_process_internal.h"
#include "reader_transfer.h"
#include "vh/io/reader_process.h"
#include "vtk_error_capture.h"

namespace vh::io {
namespace {

namespace fs = std::filesystem;

constexpr char kUsage[] =
    "usage: volume-haptics-dicom-worker load PATH OUT [--series S] [--phase N] | volume FILE OUT | list FOLDER OUT | "
    "mesh PATH OUT SCALE | seg FILE OUT | rtstruct FILE OUT | probe PATH [--after FILE] | pacs OP REQUEST OUT";

/// `probe PATH`: each DICOM file's header and pixels parsed on its own, the name printed first,
/// so that a crash names the file.
int probeMode(const fs::path& path, const fs::path& after) {
  std::error_code ec;
  const std::vector<fs::path> files = fs::is_directory(path, ec) ? detail::dicomFolderFiles(path) : std::vector<fs::path>{path};
  for (const auto& f : files) {
    if (!after.empty() && !(after < f)) continue;  // resumes past a damaged file already found
    std::cout << "file " << f.string() << std::endl;
    detail::VtkErrorCapture capture;
    auto meta = vtkSmartPointer<vtkDICOMMetaData>::New();
    auto parser = vtkSmartPointer<vtkDICOMParser>::New();
    capture.watch(parser);
    parser->SetMetaData(meta);
    parser->SetFileName(f.string().c_str());
    parser->Update();
    std::cout << "ok" << std::endl;
  }
  return 0;
}

/// `volume FILE OUT [--layer N]`: any loadVolume() input, converted here.
int volumeMode(const fs::path& path, const fs::path& out, int argc, char** argv) {
  return detail::reportingErrors([&] {
    VolumeLoadOptions in_process;
    in_process.dicom_isolation = DicomIsolation::kInProcess;
    for (int a = 4; a + 1 < argc; ++a) {
      if (std::string(argv[a]) == "--layer") in_process.nrrd_layer = std::atoi(argv[a + 1]);
    }
    const LoadedVolume v = loadVolume(path, in_process);
    detail::writeField(*v.field, v.info, out);
  });
}

/// `mesh PATH OUT SCALE`: a tool mesh, SCALE the factor from file units to metres.
int meshMode(const fs::path& path, const fs::path& out, const char* scale) {
  return detail::reportingErrors([&] {
    const haptics::TriangleMesh mesh = detail::loadMeshInProcess(path, std::strtod(scale, nullptr));
    detail::writeMesh(mesh, out, path);
  });
}

/// `seg FILE OUT`: a DICOM SEG read with DCMTK (dicom_seg.h), not yet placed on a grid.
int segMode(const fs::path& path, const fs::path& out) {
  return detail::reportingErrors([&] { detail::writeDicomSeg(detail::readDicomSegInProcess(path), out); });
}

/// `rtstruct FILE OUT`: an RT Structure Set read with DCMTK's dcmrt (dicom_rtstruct.h), not yet
/// rasterised on a scan.
int rtstructMode(const fs::path& path, const fs::path& out) {
  return detail::reportingErrors([&] { detail::writeDicomRtStruct(detail::readDicomRtStructInProcess(path), out); });
}

/// `list FOLDER OUT`: the DICOM series of a folder, with "progress DONE TOTAL" lines.
int listMode(const fs::path& folder, const fs::path& out) {
  return detail::reportingErrors([&] {
    const auto series = detail::listDicomSeriesInProcess(folder, [](int done, int total) {
      std::cout << "progress " << done << " " << total << std::endl;
    }, nullptr);
    detail::writeSeriesList(series, out);
  });
}

/// `load PATH OUT [--series S] [--phase N]`: a DICOM read, not yet converted, with "progress F"
/// lines at most every 1 %.
int loadMode(const fs::path& path, const fs::path& out, int argc, char** argv) {
  VolumeLoadOptions options;
  options.dicom_isolation = DicomIsolation::kInProcess;
  for (int i = 4; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--series") options.dicom_series = argv[i + 1];
    else if (key == "--phase") options.dicom_phase = std::atoi(argv[i + 1]);
  }
  double last = -1.0;
  options.progress = [&](double f) {
    if (f - last >= 0.01 || f >= 1.0) {
      last = f;
      std::cout << "progress " << f << std::endl;
    }
  };
  return detail::reportingErrors([&] { detail::writeRaw(detail::loadDicomRaw(path, options), out); });
}

}  // namespace

int readerProcessMain(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << kUsage << std::endl;
    return 2;
  }
  const std::string mode = argv[1];
  const fs::path path = argv[2];
  if (mode == "probe") return probeMode(path, argc >= 5 && std::string(argv[3]) == "--after" ? fs::path(argv[4]) : fs::path());
  if (mode == "volume" && argc >= 4) return volumeMode(path, argv[3], argc, argv);
  if (mode == "mesh" && argc >= 5) return meshMode(path, argv[3], argv[4]);
  if (mode == "seg" && argc >= 4) return segMode(path, argv[3]);
  if (mode == "rtstruct" && argc >= 4) return rtstructMode(path, argv[3]);
  if (mode == "list" && argc >= 4) return listMode(path, argv[3]);
  if (mode == "load" && argc >= 4) return loadMode(path, argv[3], argc, argv);
  if (mode == "pacs") return detail::pacsProcessMain(argc, argv);
  std::cerr << kUsage << std::endl;
  return 2;
}

}  // namespace vh::io
