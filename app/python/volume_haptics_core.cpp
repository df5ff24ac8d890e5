// volume_haptics._core: the C++ side of the Python module (pybind11). Thin: each function calls
// the code the command line calls (runtime::loadScene and runHeadless for `run`, readRecording
// for `export`, computeSessionMetrics for `report`, the trajectory CSV reader and writer), so a
// study scripted in Python gets the same ticks, numbers and error messages as the command line.
// The Python-facing API, its docstrings and the NumPy / pandas views are in
// volume_haptics/__init__.py.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "vh/io/segmentation.h"
#include "vh/io/volume_loader.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/tick_columns.h"
#include "vh/runtime/recording_hdf5.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/tool_fit.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/session_metrics.h"
#include "vh/runtime/trajectory.h"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace {

using vh::runtime::TickRecord;

/// A scene loaded once (volume, tool, segmentation), run many times.
struct Scene {
  std::shared_ptr<const vh::runtime::LoadedScene> loaded;
  std::string source;
};

Scene loadScene(const vh::runtime::SceneSpec& spec, const std::string& source) {
  Scene s;
  s.source = source;
  {
    py::gil_scoped_release release;
    s.loaded = std::make_shared<const vh::runtime::LoadedScene>(vh::runtime::loadScene(spec));
  }
  return s;
}

/// The records' bytes (N x 224, TickRecord's layout) as a NumPy uint8 array.
py::array_t<std::uint8_t> recordBytes(const std::vector<TickRecord>& records) {
  py::array_t<std::uint8_t> out(static_cast<py::ssize_t>(records.size() * sizeof(TickRecord)));
  if (!records.empty()) std::memcpy(out.mutable_data(), records.data(), records.size() * sizeof(TickRecord));
  return out;
}

/// A trajectory from an (N, 8) or (N, 9) float64 array: t_s, x_m, y_m, z_m, qw, qx, qy, qz
/// [, isovalue] (NaN: the scene's).
/// @throws std::invalid_argument for another shape or as Trajectory's constructor.
vh::runtime::Trajectory trajectoryOf(const py::array_t<double, py::array::c_style | py::array::forcecast>& a) {
  if (a.ndim() != 2 || (a.shape(1) != 8 && a.shape(1) != 9)) {
    throw std::invalid_argument("trajectory: expected an (N, 8) or (N, 9) array (t_s, x_m, y_m, z_m, qw, qx, qy, qz[, "
                                "isovalue]), got shape " +
                                [&] {
                                  std::string s = "(";
                                  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
                                  return s + ")";
                                }());
  }
  const auto r = a.unchecked<2>();
  std::vector<vh::runtime::TrajectorySample> samples(static_cast<std::size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    auto& s = samples[static_cast<std::size_t>(i)];
    s.t_s = r(i, 0);
    s.X_WD.p_AB_m = Eigen::Vector3d(r(i, 1), r(i, 2), r(i, 3));
    s.X_WD.R_AB = Eigen::Quaterniond(r(i, 4), r(i, 5), r(i, 6), r(i, 7));
    if (a.shape(1) == 9) s.isovalue = r(i, 8);
  }
  return vh::runtime::Trajectory(std::move(samples));
}

py::array_t<double> trajectoryArray(const vh::runtime::Trajectory& t) {
  const py::ssize_t cols = t.hasIsovalues() ? 9 : 8;
  py::array_t<double> out({static_cast<py::ssize_t>(t.size()), cols});
  auto w = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < t.size(); ++i) {
    const auto& s = t.samples()[i];
    const auto& q = s.X_WD.R_AB;
    const double row[9] = {s.t_s, s.X_WD.p_AB_m.x(), s.X_WD.p_AB_m.y(), s.X_WD.p_AB_m.z(), q.w(), q.x(), q.y(), q.z(),
                           s.isovalue};
    for (py::ssize_t c = 0; c < cols; ++c) w(static_cast<py::ssize_t>(i), c) = row[c];
  }
  return out;
}

py::tuple recordingTuple(const vh::runtime::Recording& r) {
  py::list events;
  for (const auto& e : r.events) events.append(py::make_tuple(e.time_s, e.tick, e.type, e.detail_json));
  return py::make_tuple(r.version, r.metadata_json, recordBytes(r.records), events, r.warnings, r.chunks,
                        r.dropped_records, r.bytes_ignored, r.event_chunks, r.damaged_regions, r.ended, r.end_status);
}

/// The inverse of recordingTuple(): a Recording from a Python Recording's fields.
/// @throws std::invalid_argument when the tick bytes are not whole TickRecords.
vh::runtime::Recording recordingOf(const py::tuple& t) {
  if (t.size() != 12) throw std::invalid_argument("recording: expected the 12 fields of read_recording()");
  vh::runtime::Recording r;
  r.version = t[0].cast<std::uint32_t>();
  r.metadata_json = t[1].cast<std::string>();
  const std::string bytes = t[2].cast<py::bytes>();
  if (bytes.size() % sizeof(TickRecord) != 0)
    throw std::invalid_argument("recording: the ticks are " + std::to_string(bytes.size()) + " bytes, not a multiple of " +
                                std::to_string(sizeof(TickRecord)));
  r.records.resize(bytes.size() / sizeof(TickRecord));
  if (!bytes.empty()) std::memcpy(r.records.data(), bytes.data(), bytes.size());
  for (const py::handle e : t[3].cast<py::list>()) {
    const auto ev = e.cast<py::tuple>();
    r.events.push_back({ev[0].cast<double>(), ev[1].cast<std::uint64_t>(), ev[2].cast<std::string>(),
                        ev[3].cast<std::string>()});
  }
  r.warnings = t[4].cast<std::vector<std::string>>();
  r.chunks = t[5].cast<std::size_t>();
  r.dropped_records = t[6].cast<std::uint64_t>();
  r.bytes_ignored = t[7].cast<std::uint64_t>();
  r.event_chunks = t[8].cast<std::size_t>();
  r.damaged_regions = t[9].cast<std::size_t>();
  r.ended = t[10].cast<bool>();
  r.end_status = t[11].cast<std::uint32_t>();
  return r;
}

/// A recording's session metrics (`report --table`'s): (identity dict, [(key, label, unit,
/// value)], [segment dicts], notices).
py::tuple sessionMetricsTuple(const fs::path& path, double force_threshold_N, double derivative_step_s) {
  vh::runtime::MetricsOptions options;
  options.force_threshold_N = force_threshold_N;
  options.derivative_step_s = derivative_step_s;
  vh::runtime::SessionMetrics metrics;
  {
    py::gil_scoped_release release;
    metrics = vh::runtime::computeSessionMetrics(vh::runtime::readRecording(path), options);
  }
  py::dict identity;
  identity["scene"] = metrics.scene;
  identity["dataset_sha256"] = metrics.dataset_sha256;
  identity["label"] = vh::runtime::cohortLabel(metrics, path);  // as `report --table` gives it
  identity["start_time_utc"] = metrics.start_time_utc;
  py::list values;
  for (const auto& v : vh::runtime::metricValues(metrics)) values.append(py::make_tuple(v.key, v.label, v.unit, v.value));
  py::list segments;
  for (const auto& s : metrics.segments) {
    py::dict d;
    d["name"] = s.name;
    d["critical"] = s.critical;
    d["time_in_contact_s"] = s.time_in_contact_s;
    d["peak_force_N"] = s.peak_force_N;
    d["touches"] = s.touches;
    d["removed_voxels"] = s.removed_voxels;
    d["removed_mm3"] = s.removed_mm3;
    segments.append(d);
  }
  return py::make_tuple(identity, values, segments, metrics.notices);
}

/// The scan's voxels as felt (data units: after rescale, SUV, NIfTI scaling), float64, shape
/// (nx, ny, nz) indexed [i, j, k] (Fortran order: i fastest, as the grid stores them).
py::array_t<double> arrayOf(const vh::haptics::ScalarVolume& field) {
  const auto& d = field.geometry().dims;
  py::array_t<double, py::array::f_style> out({static_cast<py::ssize_t>(d[0]), static_cast<py::ssize_t>(d[1]),
                                               static_cast<py::ssize_t>(d[2])});
  double* v = out.mutable_data();
  {
    py::gil_scoped_release release;
    std::size_t n = 0;
    for (int k = 0; k < d[2]; ++k)
      for (int j = 0; j < d[1]; ++j)
        for (int i = 0; i < d[0]; ++i) v[n++] = field.voxel(i, j, k);
  }
  return out;
}
py::array_t<double> volumeArray(const Scene& s) { return arrayOf(*s.loaded->volume.field); }

/// Index -> patient LPS [m]: 4 x 4, columns the i, j, k axes scaled by the spacing, then the
/// centre of voxel (0, 0, 0) (VolumeGeometry::indexToWorld()).
py::array_t<double> affineOf(const vh::haptics::VolumeGeometry& g) {
  py::array_t<double> out({4, 4});
  auto a = out.mutable_unchecked<2>();
  const Eigen::Matrix4d m = g.indexToWorld();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) a(r, c) = m(r, c);
  return out;
}
py::array_t<double> affineLps(const Scene& s) { return affineOf(s.loaded->volume.field->geometry()); }

/// A volume from a NumPy array (nx, ny, nz) indexed [i, j, k] placed by `affine` (4 x 4, index
/// -> patient LPS [m], voxel centres at integer indices), stored as float32 (as a float NIfTI).
/// @throws std::invalid_argument (ValueError) for another shape, fewer than 2 voxels along an
///         axis, values that are not finite, an affine that is not finite, not [.. ; 0 0 0 1],
///         sheared, or with a voxel side below 1 um.
vh::io::LoadedVolume volumeOfArray(const py::array_t<double, py::array::f_style | py::array::forcecast>& values,
                                   const py::array_t<double, py::array::c_style | py::array::forcecast>& affine) {
  if (values.ndim() != 3) throw std::invalid_argument("volume array: expected 3 dimensions (nx, ny, nz)");
  if (affine.ndim() != 2 || affine.shape(0) != 4 || affine.shape(1) != 4)
    throw std::invalid_argument("volume affine_LPS_m: expected a 4 x 4 array");
  vh::haptics::VolumeGeometry g;
  for (int a = 0; a < 3; ++a) {
    if (values.shape(a) < 2 || values.shape(a) > 100000)
      throw std::invalid_argument("volume array: " + std::to_string(values.shape(a)) + " voxels along axis " +
                                  std::to_string(a) + " (2 to 100000)");
    g.dims[static_cast<std::size_t>(a)] = static_cast<int>(values.shape(a));
  }
  Eigen::Matrix4d A;
  const auto a4 = affine.unchecked<2>();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) A(r, c) = a4(r, c);
  if (!A.allFinite() || A.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
    throw std::invalid_argument("volume affine_LPS_m: expected finite numbers with a last row of 0 0 0 1");
  for (int a = 0; a < 3; ++a) {
    const double side_m = A.block<3, 1>(0, a).norm();
    if (!(side_m >= vh::io::kMinVoxelSide_m))
      throw std::invalid_argument("volume affine_LPS_m: voxel side " + std::to_string(side_m) + " m along axis " +
                                  std::to_string(a) + " (at least 1 um)");
    g.spacing_m[a] = side_m;
    g.direction_W.col(a) = A.block<3, 1>(0, a) / side_m;
  }
  if (!(g.direction_W.transpose() * g.direction_W).isApprox(Eigen::Matrix3d::Identity(), 1e-9))
    throw std::invalid_argument("volume affine_LPS_m: the axes are not orthogonal (sheared grids are not supported)");
  g.origin_W_m = A.block<3, 1>(0, 3);
  std::vector<float> voxels(g.voxelCount());
  const double* v = values.data();
  for (std::size_t n = 0; n < voxels.size(); ++n) {
    if (!std::isfinite(v[n])) throw std::invalid_argument("volume array: holds NaN or infinite values");
    voxels[n] = static_cast<float>(v[n]);
  }
  auto field = std::make_shared<const vh::haptics::ScalarVolume>(vh::haptics::ScalarVolume::FromVoxels(g, voxels));
  vh::io::LoadedVolume volume;
  volume.image = vh::io::imageFromField(field);
  volume.field = std::move(field);
  volume.info.source = "array";
  volume.info.format = "NumPy array";
  volume.info.description = "array";
  return volume;
}

/// Scene and the functions that load one.
void bindScenes(py::module_& m) {
  py::class_<Scene>(m, "Scene",
                    "A scene loaded once (volume, tool, segmentation, coupling), to run many trajectories on.\n\n"
                    "Made by load_scene(). Read-only attributes: source (the file, or \"scene dict\"), volume_dims "
                    "[nx, ny, nz], volume_spacing_m (3 floats [m]), isovalue (data units, as loaded), volume_format "
                    "(\"NIfTI-1\", \"DICOM\", ...), volume_notices (what the loader corrected or chose, one sentence "
                    "each), volume (the voxels as a NumPy array), affine_LPS_m and direction_LPS (where they are).")
      .def_readonly("source", &Scene::source)
      .def_property_readonly("volume_dims", [](const Scene& s) { return s.loaded->volume.field->geometry().dims; })
      .def_property_readonly("volume_spacing_m",
                             [](const Scene& s) {
                               const auto& sp = s.loaded->volume.field->geometry().spacing_m;
                               return std::array<double, 3>{sp.x(), sp.y(), sp.z()};
                             })
      .def_property_readonly("isovalue", [](const Scene& s) { return s.loaded->isovalue; })
      .def_property_readonly("volume_notices", [](const Scene& s) { return s.loaded->volume.info.notices; })
      .def_property_readonly("volume_format", [](const Scene& s) { return s.loaded->volume.info.format; })
      .def_property_readonly("volume", &volumeArray,
                             "The scan's voxels as felt (data units: after rescale, SUV or NIfTI scaling), a new "
                             "float64 array of shape (nx, ny, nz) indexed [i, j, k]; voxel (i, j, k) is centred at "
                             "affine_LPS_m @ [i, j, k, 1].")
      .def_property_readonly("affine_LPS_m", &affineLps,
                             "Index -> patient LPS [m], 4 x 4: the voxel centre of (i, j, k) is affine_LPS_m @ "
                             "[i, j, k, 1] (voxel centres at integer indices; columns 0..2 the i, j, k axes times "
                             "the spacing, column 3 the centre of voxel (0, 0, 0)). The frame the tool is run in.")
      .def_property_readonly("direction_LPS",
                             [](const Scene& s) {
                               const auto& D = s.loaded->volume.field->geometry().direction_W;
                               py::array_t<double> out({3, 3});
                               auto a = out.mutable_unchecked<2>();
                               for (int r = 0; r < 3; ++r)
                                 for (int c = 0; c < 3; ++c) a(r, c) = D(r, c);
                               return out;
                             },
                             "The grid's axes in patient LPS, 3 x 3 (columns: unit i, j, k directions).")
      .def(
          "tool_fit",
          [](const Scene& s, double ns_per_work) {
            vh::runtime::ToolFitOptions options;
            options.ns_per_work = ns_per_work;
            vh::runtime::ToolFit fit;
            {
              py::gil_scoped_release release;
              fit = vh::runtime::checkToolFit(vh::runtime::LiveValues::initial(*s.loaded), options);
            }
            return py::module_::import("json").attr("loads")(fit.toJson());
          },
          py::arg("ns_per_work") = 0.0,
          "The fit check: whether this computer renders the scene's tool on time (its worst ticks cut by the "
          "solver's deadline at most 0.1 % of the time, the proxy at most 0.5 mm behind), from a warm-up touch of "
          "the tool on the surface (about a second or less), and when not, the finest coarser point spacing that "
          "fits. ns_per_work: this computer's cost of one work unit [ns]; 0 measures it. Returns a dict: fits, "
          "summary (one line), ns_per_work, fixed_us, work_budget, lanes, warmup_s, ticks, cut_ticks, "
          "behind_max_m, work_max, spacing_m, points, felt_gap_m, suggested_spacing_m / suggested_points / "
          "suggested_felt_gap_m (None when it fits or nothing coarser does). See docs/command-line.md, run.");

  m.def("load_scene_file", [](const fs::path& path) { return loadScene(vh::runtime::loadSceneFile(path), path.string()); },
        py::arg("path"));
  m.def(
      "load_scene_json",
      [](const std::string& json_text, const std::string& source, const fs::path& base_dir) {
        return loadScene(vh::runtime::parseScene(json_text, source, base_dir), source);
      },
      py::arg("json_text"), py::arg("source"), py::arg("base_dir"));
  m.def(
      "load_scene_array",
      [](const std::string& json_text, const std::string& source, const fs::path& base_dir,
         const py::array_t<double, py::array::f_style | py::array::forcecast>& values,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& affine, const py::object& labels,
         const std::map<int, std::string>& names) {
        vh::io::LoadedVolume volume = volumeOfArray(values, affine);
        // The text's volume (and segmentation) path is a stand-in (a built-in the parser takes
        // without a file): the arrays are the volume and the label map, named so in reports.
        vh::runtime::SceneSpec spec = vh::runtime::parseScene(json_text, source, base_dir);
        spec.volume.path = vh::runtime::kArrayVolumePath;
        std::optional<vh::io::LoadedSegmentation> segmentation;
        if (!labels.is_none()) {
          const auto label_values = labels.cast<py::array_t<double, py::array::f_style | py::array::forcecast>>();
          if (label_values.ndim() != 3 || label_values.shape(0) != values.shape(0) ||
              label_values.shape(1) != values.shape(1) || label_values.shape(2) != values.shape(2))
            throw std::invalid_argument("segmentation labels: expected the volume's shape (nx, ny, nz)");
          if (!spec.segmentation) throw std::invalid_argument("segmentation labels: the scene has no segmentation section");
          spec.segmentation->path = vh::runtime::kArrayVolumePath;
          segmentation = vh::io::segmentationFromLabels(volumeOfArray(label_values, affine).field, "label array", names);
        }
        Scene s;
        s.source = source;
        py::gil_scoped_release release;
        s.loaded = std::make_shared<const vh::runtime::LoadedScene>(
            segmentation ? vh::runtime::loadScene(spec, std::move(volume), std::move(*segmentation))
                         : vh::runtime::loadScene(spec, std::move(volume)));
        return s;
      },
      py::arg("json_text"), py::arg("source"), py::arg("base_dir"), py::arg("values"), py::arg("affine_LPS_m"),
      py::arg("labels") = py::none(), py::arg("names") = std::map<int, std::string>{});
}

/// run() and read_recording(): a headless run's report and recording, and a recording read.
void bindRuns(py::module_& m) {
  m.def(
      "run",
      [](const Scene& scene, const py::array_t<double, py::array::c_style | py::array::forcecast>& trajectory,
         const fs::path& record, double servo_rate_Hz, double verify_step_voxels, bool lag_reference,
         const std::string& trajectory_name) {
        const vh::runtime::Trajectory t = trajectoryOf(trajectory);
        vh::runtime::RunOptions options;
        options.servo_rate_Hz = servo_rate_Hz;
        options.verify_step_voxels = verify_step_voxels;
        options.lag_reference = lag_reference;
        options.record = record;
        vh::runtime::RunReport report;
        vh::runtime::Recording recording;
        {
          py::gil_scoped_release release;  // the run and the read touch no Python object
          report = vh::runtime::runHeadless(*scene.loaded, t, options);
          report.trajectory = trajectory_name;
          recording = vh::runtime::readRecording(record);
        }
        return py::make_tuple(report.toJson(), recordingTuple(recording));
      },
      py::arg("scene"), py::arg("trajectory"), py::arg("record"), py::arg("servo_rate_Hz"),
      py::arg("verify_step_voxels"), py::arg("lag_reference"), py::arg("trajectory_name"));

  m.def(
      "read_recording",
      [](const fs::path& path) {
        vh::runtime::Recording r;
        {
          py::gil_scoped_release release;
          r = vh::runtime::readRecording(path);
        }
        return recordingTuple(r);
      },
      py::arg("path"));

  m.def(
      "drilled_volume",
      [](const py::tuple& recording) {
        const vh::runtime::Recording r = recordingOf(recording);
        std::shared_ptr<const vh::haptics::ScalarVolume> drilled;
        {
          py::gil_scoped_release release;
          const vh::runtime::LoadedScene scene =
              vh::runtime::loadScene(vh::runtime::sceneFromSessionMetadata(r.metadata_json));
          std::string difference;
          try {
            drilled = vh::runtime::drilledFieldAtEnd(scene, r, difference);
          } catch (const std::invalid_argument& e) {  // no drill, no records: about the recording
            throw std::runtime_error(std::string("drilled_volume: ") + e.what());
          }
          if (drilled == nullptr) throw std::runtime_error("drilled_volume: " + difference);
        }
        return py::make_tuple(arrayOf(*drilled), affineOf(drilled->geometry()));
      },
      py::arg("recording"));
  m.def(
      "write_recording_hdf5",
      [](const py::tuple& recording, const fs::path& path, bool volume) {
        const vh::runtime::Recording r = recordingOf(recording);
        py::gil_scoped_release release;
        if (!volume) {
          vh::runtime::writeRecordingHdf5(r, path);
          return std::string();
        }
        return vh::runtime::writeRecordingHdf5WithVolume(r, path);
      },
      py::arg("recording"), py::arg("path"), py::arg("volume"));
}

/// Trajectories: write, read and check (N x 8 or 9 arrays).
void bindTrajectories(py::module_& m) {
  m.def(
      "write_trajectory",
      [](const fs::path& path, const py::array_t<double, py::array::c_style | py::array::forcecast>& trajectory) {
        vh::runtime::writeTrajectoryCsv(trajectoryOf(trajectory), path);
      },
      py::arg("path"), py::arg("trajectory"));
  m.def("read_trajectory", [](const fs::path& path) { return trajectoryArray(vh::runtime::loadTrajectoryCsv(path)); },
        py::arg("path"));
  m.def(
      "check_trajectory",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& trajectory) {
        return trajectoryArray(trajectoryOf(trajectory));
      },
      py::arg("trajectory"));
}

/// session_metrics(): sessionMetricsTuple() of a recording.
void bindSessionMetrics(py::module_& m) {
  m.def(
      "session_metrics",
      [](const fs::path& path, double force_threshold_N, double derivative_step_s) {
        return sessionMetricsTuple(path, force_threshold_N, derivative_step_s);
      },
      py::arg("path"), py::arg("force_threshold_N"), py::arg("derivative_step_s"));
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "C++ side of volume_haptics (see volume_haptics/__init__.py for the API).";
  // io::LoadError (a volume, segmentation or mesh that cannot be read) as its own exception;
  // std::runtime_error becomes RuntimeError, std::invalid_argument ValueError (pybind11's own
  // translation), each with the message the command line prints after "volume-haptics: error: ".
  py::register_exception<vh::io::LoadError>(m, "LoadError", PyExc_RuntimeError);
  m.attr("TICK_RECORD_BYTES") = sizeof(TickRecord);
  // The tick columns' one table (tick_columns.h), in `export --csv`'s order: (name, unit,
  // description, byte offset in a record, NumPy type). TICK_DTYPE and CSV_COLUMNS are built on it.
  py::list columns;
  for (const vh::runtime::TickColumn& c : vh::runtime::tickColumns()) {
    const char* numpy_type = "<f8";
    switch (c.kind) {
      case vh::runtime::TickColumn::kF64: numpy_type = "<f8"; break;
      case vh::runtime::TickColumn::kU64: numpy_type = "<u8"; break;
      case vh::runtime::TickColumn::kU32: numpy_type = "<u4"; break;
      case vh::runtime::TickColumn::kI32: numpy_type = "<i4"; break;
      case vh::runtime::TickColumn::kI64: numpy_type = "<i8"; break;
    }
    columns.append(py::make_tuple(c.name, c.unit, c.description, c.offset, numpy_type));
  }
  m.attr("TICK_COLUMNS") = columns;
  m.attr("RECORDING_FORMAT_VERSION") = vh::runtime::kRecordingFormatVersion;

  bindScenes(m);
  bindRuns(m);
  bindTrajectories(m);
  bindSessionMetrics(m);
}
