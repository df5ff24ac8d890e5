// Every bad input gives one LoadError whose message names the file and the problem; VTK's own
// error text never reaches stderr. Corrupt copies are written to temporary folders; the shared
// datasets are never modified.
#include <fstream>

#include <gtest/gtest.h>
#include <vtkImageData.h>
#include <vtkMetaImageWriter.h>
#include <vtkPointData.h>
#include <vtkShortArray.h>
#include <vtkSmartPointer.h>

#include "io_test_support.h"
#include "vh/io/volume_loader.h"

namespace {

namespace fs = std::filesystem;
using vh::io::loadMesh;
using vh::io::loadVolume;
using vh::io::test::loadErrorOf;
using vh::io::test::readFile;
using vh::io::test::TempDir;
using vh::io::test::writeFile;


/// Copies every file of a shared folder into `to`.
void copyFolder(const fs::path& from, const fs::path& to) {
  fs::create_directories(to);
  for (const auto& e : fs::directory_iterator(from)) {
    fs::copy_file(e.path(), to / e.path().filename(), fs::copy_options::overwrite_existing);
    fs::permissions(to / e.path().filename(), fs::perms::owner_read | fs::perms::owner_write,
                    fs::perm_options::add);
  }
}

/// Replaces the first occurrence of `from` (same length as `to`) in a file.
void patchFile(const fs::path& file, const std::string& from, const std::string& to) {
  ASSERT_EQ(from.size(), to.size());
  std::string bytes = readFile(file);
  const auto pos = bytes.find(from);
  ASSERT_NE(pos, std::string::npos) << "pattern not found in " << file;
  bytes.replace(pos, from.size(), to);
  writeFile(file, bytes);
}

void truncateFile(const fs::path& file, std::size_t size) {
  std::string bytes = readFile(file);
  ASSERT_GT(bytes.size(), size);
  writeFile(file, bytes.substr(0, size));
}

// ---- paths and formats ----------------------------------------------------------------------

TEST(LoadErrors, MissingPath) {
  const fs::path p = "/nonexistent/vh/volume.nrrd";
  const std::string msg = loadErrorOf([&] { loadVolume(p); });
  EXPECT_CONTAINS(msg, p.string());
  EXPECT_CONTAINS(msg, "no such file");
}

TEST(LoadErrors, FolderWithoutDicom) {
  TempDir tmp("no_dicom");
  writeFile(tmp / "readme.txt", "nothing to see here\n");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp.path()); });
  EXPECT_CONTAINS(msg, tmp.path().string());
  EXPECT_CONTAINS(msg, "no DICOM image series found");
}

TEST(LoadErrors, EmptyFolder) {
  TempDir tmp("empty_folder");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp.path()); });
  EXPECT_CONTAINS(msg, "no DICOM image series found");
}

TEST(LoadErrors, FileThatIsNotAVolume) {
  TempDir tmp("not_volume");
  writeFile(tmp / "notes.txt", "just some text, no voxels\n");
  std::string msg = loadErrorOf([&] { loadVolume(tmp / "notes.txt"); });
  EXPECT_CONTAINS(msg, "notes.txt");
  EXPECT_CONTAINS(msg, "not a volume");
  // No extension: tried as DICOM.
  writeFile(tmp / "I10", "just some text, no voxels\n");
  msg = loadErrorOf([&] { loadVolume(tmp / "I10"); });
  EXPECT_CONTAINS(msg, "I10");
  EXPECT_CONTAINS(msg, "not a volume");
}

TEST(LoadErrors, EmptyFile) {
  TempDir tmp("empty_file");
  writeFile(tmp / "empty.nrrd", "");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "empty.nrrd"); });
  EXPECT_CONTAINS(msg, "empty.nrrd");
  EXPECT_CONTAINS(msg, "empty file");
}

TEST(LoadErrors, VtkErrorsDoNotReachStderr) {
  TempDir tmp("stderr");
  const std::string header =
      "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n";
  // A gzip header followed by a broken deflate stream: zlib fails inside vtkNrrdReader.
  writeFile(tmp / "bad_gzip.nrrd",
            header + std::string("\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03", 10) +
                "\xff\xff\xff\xff garbage that does not inflate");
  // loadErrorOf also checks that nothing reached stderr.
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "bad_gzip.nrrd"); });
  EXPECT_CONTAINS(msg, "bad_gzip.nrrd");
  EXPECT_CONTAINS(msg, "corrupt or truncated gzip voxel data");
}

// ---- DICOM -------------------------------------------------------------------------------------

TEST(LoadErrors, CorruptDicomFile) {
  TempDir tmp("corrupt_dicom");
  std::string garbage(128, '\0');
  garbage += "DICM";
  for (int i = 0; i < 4000; ++i) garbage += static_cast<char>((i * 7919) % 251);
  writeFile(tmp / "garbage.dcm", garbage);
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "garbage.dcm"); });
  EXPECT_CONTAINS(msg, "garbage.dcm");
  EXPECT_CONTAINS(msg, "not a readable DICOM image");
}

TEST(LoadErrors, TruncatedDicomSliceInSeries) {
  VH_REQUIRE_SHARED(src, "ct/ct-head-small");
  TempDir tmp("truncated_dicom");
  copyFolder(src, tmp.path());
  truncateFile(tmp / "CTHead50.dcm", 3000);  // header intact, pixel data cut short
  const std::string msg = loadErrorOf([&] { loadVolume(tmp.path()); });
  EXPECT_CONTAINS(msg, tmp.path().string());
  EXPECT_CONTAINS(msg, "CTHead50.dcm");
  EXPECT_CONTAINS(msg, "corrupt");
}

TEST(LoadErrors, InconsistentRowsInSeries) {
  VH_REQUIRE_SHARED(src, "ct/ct-head-small");
  TempDir tmp("inconsistent_rows");
  copyFolder(src, tmp.path());
  // (0028,0010) Rows US 64 -> 32 in one file.
  patchFile(tmp / "CTHead7.dcm", std::string("\x28\x00\x10\x00US\x02\x00\x40\x00", 10),
            std::string("\x28\x00\x10\x00US\x02\x00\x20\x00", 10));
  const std::string msg = loadErrorOf([&] { loadVolume(tmp.path()); });
  EXPECT_CONTAINS(msg, tmp.path().string());
  EXPECT_CONTAINS(msg, "inconsistent slices");
  EXPECT_CONTAINS(msg, "CTHead7.dcm");
  EXPECT_CONTAINS(msg, "Rows");
}

TEST(LoadErrors, InconsistentPixelSpacingInSeries) {
  VH_REQUIRE_SHARED(src, "ct/ct-head-small");
  TempDir tmp("inconsistent_spacing");
  copyFolder(src, tmp.path());
  // (0028,0030) PixelSpacing DS "3.200000\3.200000" -> 3.1 in one file.
  const std::string tag("\x28\x00\x30\x00" "DS\x12\x00", 8);
  patchFile(tmp / "CTHead12.dcm", tag + "3.200000\\3.200000", tag + "3.100000\\3.100000");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp.path()); });
  EXPECT_CONTAINS(msg, "inconsistent slices");
  EXPECT_CONTAINS(msg, "CTHead12.dcm");
  EXPECT_CONTAINS(msg, "PixelSpacing");
}

// ---- NRRD --------------------------------------------------------------------------------------

TEST(LoadErrors, TruncatedAttachedRawNrrd) {
  TempDir tmp("truncated_nrrd");
  const std::string header =
      "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 3 2\nendian: little\nencoding: raw\n\n";
  writeFile(tmp / "cut.nrrd", header + std::string(10, '\0'));
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "cut.nrrd"); });
  EXPECT_CONTAINS(msg, (tmp / "cut.nrrd").string());
  EXPECT_CONTAINS(msg, "truncated: expected 48 bytes of voxel data, found 10");
}

TEST(LoadErrors, TruncatedSliceFileOfDetachedNrrd) {
  VH_REQUIRE_SHARED(src, "nrrd/headsq-quarter");
  TempDir tmp("truncated_slice");
  copyFolder(src, tmp.path());
  truncateFile(tmp / "quarter.93", 1000);
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "quarter.nhdr"); });
  EXPECT_CONTAINS(msg, "quarter.nhdr");
  EXPECT_CONTAINS(msg, "truncated: data file quarter.93 holds 1000 of the 8192 bytes");
}

TEST(LoadErrors, MissingSliceFileOfDetachedNrrd) {
  VH_REQUIRE_SHARED(src, "nrrd/headsq-quarter");
  TempDir tmp("missing_slice_file");
  copyFolder(src, tmp.path());
  fs::remove(tmp / "quarter.50");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "quarter.nhdr"); });
  EXPECT_CONTAINS(msg, "quarter.nhdr");
  EXPECT_CONTAINS(msg, "quarter.50 is missing");
}

TEST(LoadErrors, TruncatedGzipNrrd) {
  VH_REQUIRE_SHARED(src, "nrrd/mr-brain/brain1_image.nrrd");
  TempDir tmp("truncated_gzip");
  fs::copy_file(src, tmp / "brain1_image.nrrd");
  fs::permissions(tmp / "brain1_image.nrrd", fs::perms::owner_write, fs::perm_options::add);
  truncateFile(tmp / "brain1_image.nrrd", readFile(src).size() / 2);
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "brain1_image.nrrd"); });
  EXPECT_CONTAINS(msg, "brain1_image.nrrd");
  EXPECT_CONTAINS(msg, "corrupt or truncated gzip");
}

TEST(LoadErrors, TruncatedDetachedGzipNrrd) {
  VH_REQUIRE_SHARED(src, "classic/engine");
  TempDir tmp("truncated_engine");
  copyFolder(src, tmp.path());
  truncateFile(tmp / "engine_256x256x128_uint8.raw.gz", 100000);
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "engine.nhdr"); });
  EXPECT_CONTAINS(msg, "engine.nhdr");
  EXPECT_CONTAINS(msg, "corrupt or truncated gzip");
}

TEST(LoadErrors, MalformedNrrdHeaders) {
  TempDir tmp("bad_headers");
  writeFile(tmp / "garbled.nrrd", "NRRD0004\nthis line has no colon\n\n");
  std::string msg = loadErrorOf([&] { loadVolume(tmp / "garbled.nrrd"); });
  EXPECT_CONTAINS(msg, "garbled.nrrd");
  EXPECT_CONTAINS(msg, "malformed NRRD header line 2");

  writeFile(tmp / "flat.nrrd",
            "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 4 4\nencoding: raw\n\n" +
                std::string(16, 'x'));
  msg = loadErrorOf([&] { loadVolume(tmp / "flat.nrrd"); });
  EXPECT_CONTAINS(msg, "is a 2-D NRRD");

  writeFile(tmp / "hex.nrrd",
            "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: hex\n\n0102");
  msg = loadErrorOf([&] { loadVolume(tmp / "hex.nrrd"); });
  EXPECT_CONTAINS(msg, "unsupported NRRD encoding \"hex\"");

  writeFile(tmp / "nomagic.nrrd", "NRRX\ntype: uchar\n\n");
  msg = loadErrorOf([&] { loadVolume(tmp / "nomagic.nrrd"); });
  EXPECT_CONTAINS(msg, "not a NRRD file");

  writeFile(tmp / "oneslice.nrrd",
            "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 1\nencoding: raw\n\n" +
                std::string(16, 'x'));
  msg = loadErrorOf([&] { loadVolume(tmp / "oneslice.nrrd"); });
  EXPECT_CONTAINS(msg, "oneslice.nrrd");
  EXPECT_CONTAINS(msg, "not a 3-D volume: 4x4x1");

  writeFile(tmp / "units.nrrd",
            "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: left-posterior-superior\n"
            "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace units: \"furlong\" \"mm\" \"mm\"\n"
            "encoding: raw\n\n" + std::string(8, 'x'));
  msg = loadErrorOf([&] { loadVolume(tmp / "units.nrrd"); });
  EXPECT_CONTAINS(msg, "unsupported length unit \"furlong\"");
}

TEST(LoadErrors, GzipEncodingWithoutGzipData) {
  TempDir tmp("not_gzip");
  writeFile(tmp / "plain.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                                "encoding: gzip\n\nthis is not gzip data at all");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "plain.nrrd"); });
  EXPECT_CONTAINS(msg, "plain.nrrd: corrupt gzip voxel data");
}

TEST(LoadErrors, TruncatedAsciiNrrd) {
  TempDir tmp("ascii_cut");
  writeFile(tmp / "cut.nrrd",
            "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3\n");
  std::string msg = loadErrorOf([&] { loadVolume(tmp / "cut.nrrd"); });
  EXPECT_CONTAINS(msg, "truncated: expected 8 ascii voxel values, found 3");
  writeFile(tmp / "words.nrrd",
            "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 x\n");
  msg = loadErrorOf([&] { loadVolume(tmp / "words.nrrd"); });
  EXPECT_CONTAINS(msg, "corrupt ascii voxel data");
}

// ---- MetaImage ---------------------------------------------------------------------------------

TEST(LoadErrors, TruncatedMetaImageRaw) {
  TempDir tmp("truncated_mhd");
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(8, 8, 8);
  auto values = vtkSmartPointer<vtkShortArray>::New();
  values->SetNumberOfTuples(512);
  values->FillValue(7);
  image->GetPointData()->SetScalars(values);
  auto writer = vtkSmartPointer<vtkMetaImageWriter>::New();
  writer->SetInputData(image);
  writer->SetFileName((tmp / "img.mhd").string().c_str());
  writer->SetRAWFileName((tmp / "img.raw").string().c_str());
  writer->SetCompression(false);
  writer->Write();
  truncateFile(tmp / "img.raw", 100);
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "img.mhd"); });
  EXPECT_CONTAINS(msg, "img.mhd");
  EXPECT_CONTAINS(msg, "truncated: expected 1024 bytes of voxel data in img.raw, found 100");

  fs::remove(tmp / "img.raw");
  const std::string missing = loadErrorOf([&] { loadVolume(tmp / "img.mhd"); });
  EXPECT_CONTAINS(missing, "img.raw is missing");
}

TEST(LoadErrors, MetaImageWithoutDataFile) {
  TempDir tmp("bad_mha");
  writeFile(tmp / "bad.mha", "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\n");
  const std::string msg = loadErrorOf([&] { loadVolume(tmp / "bad.mha"); });
  EXPECT_CONTAINS(msg, "bad.mha");
  EXPECT_CONTAINS(msg, "no ElementDataFile");
}

// ---- meshes ------------------------------------------------------------------------------------

TEST(LoadErrors, Meshes) {
  TempDir tmp("bad_meshes");
  std::string msg = loadErrorOf([&] { loadMesh(tmp / "absent.stl"); });
  EXPECT_CONTAINS(msg, "absent.stl");
  EXPECT_CONTAINS(msg, "no such file");

  writeFile(tmp / "tool.3ds", "binary stuff");
  msg = loadErrorOf([&] { loadMesh(tmp / "tool.3ds"); });
  EXPECT_CONTAINS(msg, "unsupported mesh format \".3ds\"");

  writeFile(tmp / "garbage.stl", "this is not an STL file");
  msg = loadErrorOf([&] { loadMesh(tmp / "garbage.stl"); });
  EXPECT_CONTAINS(msg, "garbage.stl");

  writeFile(tmp / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  msg = loadErrorOf([&] { loadMesh(tmp / "points.obj"); });
  EXPECT_CONTAINS(msg, "points.obj");
  EXPECT_CONTAINS(msg, "no triangles");

  writeFile(tmp / "empty.ply", "");
  msg = loadErrorOf([&] { loadMesh(tmp / "empty.ply"); });
  EXPECT_CONTAINS(msg, "empty file");

  writeFile(tmp / "ok.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  msg = loadErrorOf([&] { loadMesh(tmp / "ok.obj", -1.0); });
  EXPECT_CONTAINS(msg, "scale_to_m");
}

}  // namespace
