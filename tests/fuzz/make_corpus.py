#!/usr/bin/env python3
"""Writes the seed corpora of tests/fuzz/corpus/<target>/ (small files, < 2 MB in all) from the
shared datasets (../shared/datasets, never copied whole) and resources/scenes, downscaled or cut.

    tests/fuzz/make_corpus.py [--datasets DIR] [--recording R.vhrec --trajectory T.csv]

The .vhrec seed comes from a real recording (`volume-haptics run --scene
resources/scenes/sphere-probe.json --trajectory T.csv --report r.json --record R.vhrec`, T a
make-trajectory CSV with its times scaled by 0.01: 46 ticks) with an event chunk appended here.
Standard library only.
"""
import argparse
import gzip
import math
import os
import pathlib
import shutil
import struct
import zlib

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent


def out(target, name, data):
    d = HERE / "corpus" / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())


def shorts_le(values):
    return struct.pack("<%dh" % len(values), *values)


def downsample(raw, dims, step, slices, dtype="<h"):
    """Every step-th voxel in plane of the given slices of a little-endian volume."""
    nx, ny, _ = dims
    size = struct.calcsize(dtype)
    vals = []
    for z in slices:
        for y in range(0, ny, step):
            for x in range(0, nx, step):
                i = ((z * ny + y) * nx + x) * size
                vals.append(struct.unpack_from(dtype, raw, i)[0])
    return vals


def nrrd_seeds(ds):
    # CT head quarter (64x64x93 shorts, one file per slice): two slices, detached header.
    q = ds / "nrrd/headsq-quarter"
    data = (q / "quarter.40").read_bytes() + (q / "quarter.41").read_bytes()
    header = ("NRRD0004\ndimension: 3\nsizes: 64 64 2\nspacings: 3.2 3.2 1.5\nendian: little\n"
              "type: short\nencoding: raw\nspace: 3D-left-handed\ndata file: in.raw\n")
    out("nrrd", "headsq-2slices-detached", header.encode() + b"\n#VHDATA#\n" + data)
    # The same, 16x16x2, attached and ascii.
    small = downsample(data, (64, 64, 2), 4, [0, 1])
    out("nrrd", "headsq-ascii.nrrd",
        "NRRD0004\ndimension: 3\nsizes: 16 16 2\nspacings: 12.8 12.8 1.5\ntype: short\n"
        "encoding: ascii\nspace: left-posterior-superior\n\n" + " ".join(map(str, small)) + "\n")
    # MR brain (256x256x25 shorts, gzip, space directions): 32x32x3, gzip, attached.
    mr = (ds / "nrrd/mr-brain/brain1_image.nrrd").read_bytes()
    end = mr.index(b"\n\n") + 2
    head = mr[:end].decode()
    vox = gzip.decompress(mr[end:])
    small = downsample(vox, (256, 256, 25), 8, [11, 12, 13])
    head = head.replace("sizes: 256 256 25", "sizes: 32 32 3")
    head = head.replace("0.78124999999999989", "6.2499999999999991")
    out("nrrd", "mr-brain-32x32x3-gzip.nrrd", head.encode() + gzip.compress(shorts_le(small), 9))
    # The same voxels raw, big endian, RAS space, float.
    floats = struct.pack(">%df" % len(small), *[float(v) for v in small])
    out("nrrd", "mr-brain-float-big-ras.nrrd",
        ("NRRD0005\ntype: float\ndimension: 3\nspace: right-anterior-superior\nsizes: 32 32 3\n"
         "space directions: (6.25,0,0) (0,6.25,0) (0,0,6.5)\nspace units: \"mm\" \"mm\" \"mm\"\n"
         "kinds: domain domain domain\nendian: big\nencoding: raw\n"
         "space origin: (-99.6,-99.6,-78)\n\n").encode() + floats)
    # Engine (256x256x128 uchar, detached gzip): 16x16x8, detached gzip.
    eng = gzip.decompress((ds / "classic/engine/engine_256x256x128_uint8.raw.gz").read_bytes())
    small = downsample(eng, (256, 256, 128), 16, range(0, 128, 16), dtype="B")
    out("nrrd", "engine-16x16x8-gzip-detached",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 16 16 8\nspacings: 16 16 16\nencoding: gzip\n"
        b"data file: in.raw\n\n#VHDATA#\n" + gzip.compress(bytes(small), 9))
    # A 4x4x4 unsigned short volume with a data file LIST.
    out("nrrd", "list-ushort-detached",
        b"NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 4 4 4\nspacings: 1 1 2\n"
        b"endian: little\nencoding: raw\nspace units: \"mm\" \"mm\" \"mm\"\ndata file: LIST\nin.raw\n"
        b"#VHDATA#\n" + struct.pack("<64H", *range(0, 6400, 100)))
    return small


def metaimage_seeds(ds):
    q = ds / "nrrd/headsq-quarter"
    data = (q / "quarter.40").read_bytes() + (q / "quarter.41").read_bytes() + (q / "quarter.42").read_bytes()
    small = shorts_le(downsample(data, (64, 64, 3), 4, [0, 1, 2]))
    head = ("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
            "TransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = -100 -100 -60\nCenterOfRotation = 0 0 0\n"
            "AnatomicalOrientation = RAI\nElementSpacing = 12.8 12.8 1.5\nDimSize = 16 16 3\n"
            "ElementType = MET_SHORT\n")
    out("metaimage", "headsq-16x16x3.mha", (head + "ElementDataFile = LOCAL\n").encode() + small)
    comp = zlib.compress(small, 9)
    out("metaimage", "headsq-16x16x3-zlib.mha",
        (head.replace("BinaryData = True\n", "BinaryData = True\nCompressedData = True\n"
                      "CompressedDataSize = %d\n" % len(comp)) + "ElementDataFile = LOCAL\n").encode() + comp)
    out("metaimage", "oblique-uchar.mha",
        b"ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementSpacing = 1 1 1\n"
        b"TransformMatrix = 0.8 0.6 0 -0.6 0.8 0 0 0 1\nOffset = 0 0 0\nElementType = MET_UCHAR\n"
        b"ElementDataFile = LOCAL\n" + bytes(range(0, 256, 4)))
    out("metaimage", "float-msb.mha",
        b"ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementSpacing = 0.5 0.5 0.5\n"
        b"ElementByteOrderMSB = True\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n" +
        struct.pack(">8f", *[0.5 * i for i in range(8)]))


def nifti1_header(dims, datatype, bitpix, pixdim, qfac=1.0, quatern=(0, 0, 0), qoffset=(0, 0, 0), srows=None,
                  scl=(0.0, 0.0), units=2, single=True, endian="<", intent=0):
    """A NIfTI-1 header (348 bytes, then the 4-byte extension flag of a .nii), fields by offset."""
    h = bytearray(348)
    struct.pack_into(endian + "i", h, 0, 348)
    struct.pack_into(endian + "8h", h, 40, len(dims), *dims, *([1] * (7 - len(dims))))
    struct.pack_into(endian + "h", h, 68, intent)
    struct.pack_into(endian + "hh", h, 70, datatype, bitpix)
    struct.pack_into(endian + "8f", h, 76, qfac, *pixdim, *([1.0] * (7 - len(pixdim))))
    struct.pack_into(endian + "f", h, 108, 352.0 if single else 0.0)
    struct.pack_into(endian + "ff", h, 112, *scl)
    h[123] = units
    struct.pack_into(endian + "hh", h, 252, 1, 1 if srows else 0)
    struct.pack_into(endian + "3f", h, 256, *quatern)
    struct.pack_into(endian + "3f", h, 268, *qoffset)
    if srows:
        struct.pack_into(endian + "12f", h, 280, *[v for row in srows for v in row])
    h[344:348] = b"n+1\0" if single else b"ni1\0"
    return bytes(h) + (b"\0\0\0\0" if single else b"")


def nifti2_header(dims, datatype, bitpix, pixdim, srows, units=2):
    """A NIfTI-2 header (540 bytes, then the extension flag), sform only."""
    h = bytearray(540)
    struct.pack_into("<i", h, 0, 540)
    h[4:12] = b"n+2\0\r\n\x1a\n"
    struct.pack_into("<hh", h, 12, datatype, bitpix)
    struct.pack_into("<8q", h, 16, len(dims), *dims, *([1] * (7 - len(dims))))
    struct.pack_into("<8d", h, 104, 1.0, *pixdim, *([1.0] * (7 - len(pixdim))))
    struct.pack_into("<q", h, 168, 544)
    struct.pack_into("<dd", h, 176, 1.0, 0.0)
    struct.pack_into("<ii", h, 344, 0, 1)
    struct.pack_into("<12d", h, 400, *[v for row in srows for v in row])
    struct.pack_into("<i", h, 500, units)
    return bytes(h) + b"\0\0\0\0"


def nifti_seeds(ds):
    q = ds / "nrrd/headsq-quarter"
    data = (q / "quarter.40").read_bytes() + (q / "quarter.41").read_bytes() + (q / "quarter.42").read_bytes()
    small = shorts_le(downsample(data, (64, 64, 3), 4, [0, 1, 2]))  # 16 x 16 x 3 int16
    # qform, rotated 90 deg about z (quaternion (0, 0, sqrt(1/2))), qfac -1, scaled values.
    out("nifti", "headsq-qform-qfac.nii",
        nifti1_header([16, 16, 3], 4, 16, [12.8, 12.8, 1.5], qfac=-1.0, quatern=(0, 0, 0.70710678),
                      qoffset=(100, -100, -60), scl=(0.5, -1024.0)) + small)
    out("nifti", "headsq-sform.nii.gz",
        gzip.compress(nifti1_header([16, 16, 3], 4, 16, [12.8, 12.8, 1.5],
                                    srows=[(-12.8, 0, 0, 100), (0, -12.8, 0, 100), (0, 0, 1.5, -60)]) + small, 9))
    # A pair, big-endian header and voxels, a 4-D label map of 2 time points.
    labels = bytes((x * y) % 4 for x in range(4) for y in range(4 * 3 * 2))
    out("nifti", "labels-4d-pair-msb",
        nifti1_header([4, 4, 3, 2], 2, 8, [1.0, 1.0, 2.0, 1.0], single=False, endian=">", intent=1002) +
        b"\n#VHDATA#\n" + labels)
    out("nifti", "float-nifti2.nii",
        nifti2_header([4, 3, 2], 16, 32, [0.5, 0.5, 0.5], [(0.5, 0, 0, -1), (0, 0.5, 0, -1), (0, 0, 0.5, 1)], units=3) +
        struct.pack("<24f", *[0.25 * i for i in range(24)]))


def mesh_seeds(ds):
    # Binary STL: the drill's first 60 triangles.
    stl = (ds / "meshes/drill/drill.stl").read_bytes()
    n = 60
    # VTK reads text unless a byte of the start is > 127.
    head = b"\xffbinary STL: 60 triangles cut from drill.stl".ljust(80, b" ")
    out("mesh", "drill-60tri.stl", b"\x00" + head + struct.pack("<I", n) + stl[84:84 + 50 * n])
    tet = [(0, 0, 0), (10, 0, 0), (0, 10, 0), (0, 0, 10)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    text = "solid tet\n"
    for f in faces:
        text += " facet normal 0 0 0\n  outer loop\n"
        for v in f:
            text += "   vertex %g %g %g\n" % tet[v]
        text += "  endloop\n endfacet\n"
    out("mesh", "tet-ascii.stl", b"\x00" + (text + "endsolid tet\n").encode())
    # OBJ: the first 300 vertices of the dental probe and the faces that use only them.
    lines = (ds / "meshes/dental-probe/dental_instrument.obj").read_text(errors="replace").splitlines()
    verts = [l for l in lines if l.startswith("v ")][:300]
    fs = []
    for l in lines:
        if l.startswith("f "):
            idx = [int(t.split("/")[0]) for t in l.split()[1:]]
            if all(0 < i <= 300 for i in idx):
                fs.append("f " + " ".join(str(i) for i in idx))
    out("mesh", "dental-probe-300v.obj", b"\x01" + ("\n".join(["# cut from dental_instrument.obj"] + verts + fs[:400]) + "\n").encode())
    obj = "o tet\n" + "".join("v %g %g %g\n" % v for v in tet) + "vn 0 0 1\nvt 0 0\n" + \
          "".join("f %d/1/1 %d/1/1 %d/1/1\n" % tuple(i + 1 for i in f) for f in faces[:3]) + \
          "f -4 -3 -2 -1\ng part\ns 1\nusemtl none\n"
    out("mesh", "tet-quad-negative.obj", b"\x01" + obj.encode())
    # PLY, ascii and binary.
    ply = ("ply\nformat ascii 1.0\ncomment tetrahedron\nelement vertex 4\nproperty float x\n"
           "property float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\n"
           "end_header\n" + "".join("%g %g %g\n" % v for v in tet) +
           "".join("3 %d %d %d\n" % f for f in faces))
    out("mesh", "tet-ascii.ply", b"\x02" + ply.encode())
    binply = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n"
              b"property double y\nproperty double z\nproperty uchar red\nelement face 4\n"
              b"property list uchar uint vertex_indices\nend_header\n")
    for v in tet:
        binply += struct.pack("<dddB", *v, 200)
    for f in faces:
        binply += struct.pack("<BIII", 3, *f)
    out("mesh", "tet-binary.ply", b"\x02" + binply)


def dicom_seeds(ds):
    d = ds / "ct/ct-head-small"
    for name in ("CTHead1.dcm", "CTHead40.dcm"):
        out("dicom", name, (d / name).read_bytes())
    # A two-frame file: CTHead40 with Number of Frames (0028,0008) "2" and CTHead41's pixels.
    b = (d / "CTHead40.dcm").read_bytes()
    k = b.find(b"\x28\x00\x10\x00US\x02\x00")
    b = b[:k] + b"\x28\x00\x08\x00IS\x02\x002 " + b[k:]
    p = b.rfind(b"\xe0\x7f\x10\x00OW")
    n = struct.unpack_from("<I", b, p + 8)[0]
    out("dicom", "CTHead40-41-two-frames.dcm",
        b[:p + 8] + struct.pack("<I", 2 * n) + b[p + 12:p + 12 + n] + (d / "CTHead41.dcm").read_bytes()[-n:])


def scene_seeds():
    for p in sorted((ROOT / "resources/scenes").glob("*.json")):
        out("scene", p.name, p.read_bytes())
    out("scene", "scripted-comments.json",
        '// a scene with every section\n{"volume": {"path": "builtin:sphere", "isovalue": 0.5},\n'
        ' /* tool */ "tool": {"mesh": "tool.stl", "scale_to_m": 1e-3, "point_count": 200,\n'
        '  "initial_pose": {"p_m": [0, 0, 0.03], "q_wxyz": [0.7071, 0, 0.7071, 0]}},\n'
        ' "coupling": {"linear_N_per_m": 500, "angular_Nm_per_rad": 0.5},\n'
        ' "device": {"kind": "scripted", "trajectory": "t.csv"}}\n')


def trajectory_seeds(trajectory):
    if trajectory:
        out("trajectory", "push-slide.csv", pathlib.Path(trajectory).read_bytes())
    rows = ["t_s,x_m,y_m,z_m,qw,qx,qy,qz"]
    for i in range(12):
        a = 0.5 * i
        rows.append("%g,%g,%g,%g,%g,0,0,%g" % (0.01 * i, 0.01 * math.cos(a), 0.01 * math.sin(a), 0.02,
                                              math.cos(a / 2), math.sin(a / 2)))
    out("trajectory", "circle.csv", "\n".join(rows) + "\n")
    out("trajectory", "no-header-crlf.csv", "0,0,0,0.1,1,0,0,0\r\n1e-3,0,0,0.09,2,0,0,0\r\n")


def recording_seeds(recording):
    if not recording:
        return
    rec = pathlib.Path(recording).read_bytes()
    # Append an event chunk ("EVNT", count, payload bytes, payload, CRC-32): one marker.
    etype = b"marker"
    detail = b'{"label":"seed"}'
    payload = struct.pack("<dQI", 0.01, 10, len(etype)) + etype + struct.pack("<I", len(detail)) + detail
    chunk = b"EVNT" + struct.pack("<II", 1, len(payload)) + payload
    chunk += struct.pack("<I", zlib.crc32(chunk) & 0xFFFFFFFF)
    out("recording", "sphere-46ticks-fixcrc", b"\x01" + rec + chunk)
    out("recording", "sphere-46ticks-asis", b"\x00" + rec)
    # The header and metadata only.
    meta = struct.unpack_from("<I", rec, 16)[0]
    out("recording", "sphere-header-only", b"\x01" + rec[:24 + meta])
    # Metadata nested as deep as the reader accepts (100 levels) and one deeper (refused as
    # damaged), and an event whose detail nests 101 deep (dropped with a warning): the bound on
    # JSON depth (recording.h: kMaxRecordingJsonDepth).
    for depth in (100, 101):
        deep = ('{"scene":' + "[" * (depth - 1) + "]" * (depth - 1) + "}").encode()
        header = rec[:16] + struct.pack("<II", len(deep), zlib.crc32(deep) & 0xFFFFFFFF)
        out("recording", "sphere-metadata-depth-%d" % depth, b"\x01" + header + deep + rec[24 + meta:])
    detail = b"[" * 101 + b"]" * 101
    payload = struct.pack("<dQI", 0.01, 10, len(etype)) + etype + struct.pack("<I", len(detail)) + detail
    chunk = b"EVNT" + struct.pack("<II", 1, len(payload)) + payload
    chunk += struct.pack("<I", zlib.crc32(chunk) & 0xFFFFFFFF)
    out("recording", "sphere-event-depth-101", b"\x01" + rec + chunk)


def device_seeds():
    def report(b):
        return bytes([len(b)]) + bytes(b)
    t = report([1] + list(struct.pack("<hhh", 120, -40, 350)))
    r = report([2] + list(struct.pack("<hhh", -5, 200, -350)))
    six = report([1] + list(struct.pack("<hhhhhh", 10, 20, 30, -10, -20, -30)))
    buttons = report([3, 0x03, 0x00]) + report([3, 0x01, 0x00, 0x00, 0x80])
    battery = report([0x17, 87])
    out("spacemouse", "navigator-translate-rotate", bytes([0x6D, 0x04, 0x26, 0xC6]) + t + r + t + r)
    out("spacemouse", "wireless-six-axes-buttons-battery", bytes([0x6F, 0x25, 0x2E, 0xC6]) + six * 3 + buttons + battery)

    def word(v):
        bits = v & 0xFFFF
        return bytes(((bits >> (4 * i)) & 0xF) + 0x41 for i in range(4))

    def status(enc, homed=7, buttons=0):
        p = b"<" + b"".join(word(e) for e in enc) + bytes([((homed << 4) | buttons) + 0x41, 0x41]) + b">"
        return p

    def transfer(serial):
        b = b"\x31\x60" + serial  # FTDI modem status, then the serial bytes
        return bytes([len(b)]) + b
    packets = b"".join(status((e, -e, 2 * e)) for e in (0, 100, -100))
    out("falcon", "status-packets", transfer(bytes([0x0A, 0x44, 0x2C, 0x0D])) + transfer(packets[:30]) + transfer(packets[30:]))
    out("falcon", "status-junk-split", transfer(b"xx<AB" + status((1500, 1500, 1500), 3, 5)[:9]) +
        transfer(status((1500, 1500, 1500), 3, 5)[9:] + status((-2000, 0, 2000))))

# ---- DICOM written here (explicit VR little endian unless said otherwise) ---------------------
# Minimal SEG, RT Structure Set and C-FIND response datasets on the fuzz targets' scan
# (fuzz_support.h smallScan(): 16 x 16 x 4 voxels of 1 mm from the origin, axes along L, P, S).
LONG_VRS = {"OB", "OW", "OF", "SQ", "UN", "UT", "UC", "UR", "OD", "OL"}


def dcm_value(vr, value):
    if vr == "SQ":
        return b"".join(dcm_item(i) for i in value)
    if vr == "US":
        return struct.pack("<%dH" % len(value), *value) if isinstance(value, (list, tuple)) else struct.pack("<H", value)
    if vr == "UL":
        return struct.pack("<%dI" % len(value), *value) if isinstance(value, (list, tuple)) else struct.pack("<I", value)
    if isinstance(value, bytes):
        return value + (b"\0" if len(value) % 2 else b"")
    b = value.encode()
    if len(b) % 2:
        b += b"\0" if vr == "UI" else b" "
    return b


def dcm_element(tag, vr, value, big=False):
    group, element = tag
    v = dcm_value(vr, value)
    e = ">" if big else "<"
    head = struct.pack(e + "HH", group, element) + vr.encode()
    if vr in LONG_VRS:
        return head + b"\0\0" + struct.pack(e + "I", len(v)) + v
    return head + struct.pack(e + "H", len(v)) + v


def dcm_elements(elements):
    return b"".join(dcm_element(*el) for el in sorted(elements, key=lambda el: el[0]))


def dcm_item(elements):
    body = dcm_elements(elements)
    return struct.pack("<HHI", 0xFFFE, 0xE000, len(body)) + body


def dcm_implicit(elements):
    """Implicit VR little endian (the default transfer syntax of a C-FIND response)."""
    out = b""
    for (group, element), vr, value in sorted(elements, key=lambda el: el[0]):
        v = dcm_value(vr, value)
        out += struct.pack("<HHI", group, element, len(v)) + v
    return out


def dcm_file(sop_class, sop_instance, elements):
    meta_rest = dcm_elements([
        ((0x0002, 0x0001), "OB", b"\0\1"),
        ((0x0002, 0x0002), "UI", sop_class),
        ((0x0002, 0x0003), "UI", sop_instance),
        ((0x0002, 0x0010), "UI", "1.2.840.10008.1.2.1"),
        ((0x0002, 0x0012), "UI", "1.2.826.0.1.3680043.9.7433.1"),
    ])
    meta = dcm_element((0x0002, 0x0000), "UL", len(meta_rest)) + meta_rest
    return b"\0" * 128 + b"DICM" + meta + dcm_elements(elements)


UID = "1.2.826.0.1.3680043.9.7433.2."


def dcm_common(modality, sop_class, n):
    return [
        ((0x0008, 0x0016), "UI", sop_class), ((0x0008, 0x0018), "UI", UID + "%d.1" % n),
        ((0x0008, 0x0020), "DA", "20260101"), ((0x0008, 0x0030), "TM", "120000"),
        ((0x0008, 0x0050), "SH", ""), ((0x0008, 0x0060), "CS", modality),
        ((0x0008, 0x0070), "LO", "VolumeHaptics"), ((0x0008, 0x0090), "PN", ""),
        ((0x0010, 0x0010), "PN", "Fuzz^Seed"), ((0x0010, 0x0020), "LO", "VH-FUZZ"),
        ((0x0010, 0x0030), "DA", ""), ((0x0010, 0x0040), "CS", ""),
        ((0x0020, 0x000D), "UI", UID + "1"), ((0x0020, 0x000E), "UI", UID + "%d.2" % n),
        ((0x0020, 0x0010), "SH", ""), ((0x0020, 0x0011), "IS", str(n)),
    ]


def code(value, meaning, scheme="SCT"):
    return [[((0x0008, 0x0100), "SH", value), ((0x0008, 0x0102), "SH", scheme), ((0x0008, 0x0104), "LO", meaning)]]


def seg_seed(name, fractional=False, overlap=False):
    """Two segments on 16 x 16 frames at z = 0..3 mm: a square per slice (BINARY: 1 bit a pixel,
    frames packed back to back; FRACTIONAL: a byte a pixel, maximum 255)."""
    rows = cols = 16
    frames = []  # (segment, z, inside(c, r))
    for z in range(4):
        frames.append((1, z, lambda c, r: 4 <= c < 12 and 4 <= r < 12))
    for z in (1, 2):
        frames.append((2, z, (lambda c, r: 6 <= c < 14 and 2 <= r < 8) if overlap else (lambda c, r: c < 3 and r < 3)))
    bits = []
    for _, _, inside in frames:
        bits += [inside(c, r) for r in range(rows) for c in range(cols)]
    if fractional:
        pixels = bytes(255 if b else 0 for b in bits)
    else:
        pixels = bytearray((len(bits) + 7) // 8)
        for n, b in enumerate(bits):
            if b:
                pixels[n >> 3] |= 1 << (n & 7)
        pixels = bytes(pixels)
    segments = [[((0x0062, 0x0003), "SQ", code("91723000", "Anatomical Structure")),
                 ((0x0062, 0x0004), "US", k), ((0x0062, 0x0005), "LO", label),
                 ((0x0062, 0x0008), "CS", "MANUAL"), ((0x0062, 0x000D), "US", lab),
                 ((0x0062, 0x000F), "SQ", code(type_code, type_meaning))]
                for k, label, lab, type_code, type_meaning in
                ((1, "Square", [21169, 53249, 46135], "39607008", "Lung"),
                 (2, "Corner", [54534, 20018, 50563], "80891009", "Heart"))]
    per_frame = [[((0x0020, 0x9111), "SQ", [[((0x0020, 0x9157), "UL", [k, z + 1])]]),
                  ((0x0020, 0x9113), "SQ", [[((0x0020, 0x0032), "DS", "0\\0\\%d" % z)]]),
                  ((0x0062, 0x000A), "SQ", [[((0x0062, 0x000B), "US", k)]])]
                 for k, z, _ in frames]
    shared = [[((0x0020, 0x9116), "SQ", [[((0x0020, 0x0037), "DS", "1\\0\\0\\0\\1\\0")]]),
               ((0x0028, 0x9110), "SQ", [[((0x0018, 0x0050), "DS", "1"), ((0x0018, 0x0088), "DS", "1"),
                                          ((0x0028, 0x0030), "DS", "1\\1")]])]]
    seg_class = "1.2.840.10008.5.1.4.1.1.66.4"
    el = dcm_common("SEG", seg_class, 7) + [
        ((0x0008, 0x0023), "DA", "20260101"), ((0x0008, 0x0033), "TM", "120000"),
        ((0x0008, 0x1090), "LO", "fuzz"), ((0x0018, 0x1000), "LO", "1"), ((0x0018, 0x1020), "LO", "1"),
        ((0x0020, 0x0013), "IS", "1"), ((0x0020, 0x0052), "UI", UID + "9"),
        ((0x0020, 0x1040), "LO", ""),
        ((0x0020, 0x9221), "SQ", [[((0x0020, 0x9164), "UI", UID + "10")]]),
        ((0x0020, 0x9222), "SQ", [[((0x0020, 0x9164), "UI", UID + "10"), ((0x0020, 0x9165), "AT", struct.pack("<HH", 0x0062, 0x000B)),
                                   ((0x0020, 0x9167), "AT", struct.pack("<HH", 0x0062, 0x000A))],
                                  [((0x0020, 0x9164), "UI", UID + "10"), ((0x0020, 0x9165), "AT", struct.pack("<HH", 0x0020, 0x0032)),
                                   ((0x0020, 0x9167), "AT", struct.pack("<HH", 0x0020, 0x9113))]]),
        ((0x0028, 0x0002), "US", 1), ((0x0028, 0x0004), "CS", "MONOCHROME2"),
        ((0x0028, 0x0008), "IS", str(len(frames))), ((0x0028, 0x0010), "US", rows), ((0x0028, 0x0011), "US", cols),
        ((0x0028, 0x0100), "US", 8 if fractional else 1), ((0x0028, 0x0101), "US", 8 if fractional else 1),
        ((0x0028, 0x0102), "US", 7 if fractional else 0), ((0x0028, 0x0103), "US", 0),
        ((0x0028, 0x2110), "CS", "00"),
        ((0x0062, 0x0001), "CS", "FRACTIONAL" if fractional else "BINARY"),
        ((0x0062, 0x0002), "SQ", segments),
        ((0x0070, 0x0080), "CS", "FUZZ"), ((0x0070, 0x0081), "LO", ""), ((0x0070, 0x0084), "PN", ""),
        ((0x5200, 0x9229), "SQ", shared), ((0x5200, 0x9230), "SQ", per_frame),
        ((0x7FE0, 0x0010), "OB", pixels if len(pixels) % 2 == 0 else pixels + b"\0"),
    ]
    if fractional:
        el += [((0x0062, 0x000E), "US", 255), ((0x0062, 0x0010), "CS", "PROBABILITY")]
    out("seg", name, b"\0" + dcm_file(seg_class, UID + "7.1", el))
    out("seg", name + "-on-scan", b"\1" + dcm_file(seg_class, UID + "7.1", el))


def square(x0, y0, x1, y1, z):
    return "\\".join("%g\\%g\\%g" % (x, y, z) for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)))


def rtstruct_seeds():
    rois = [((1, "Box", "255\\0\\0"), [("CLOSED_PLANAR", square(3, 3, 12, 12, z)) for z in range(4)] +
             [("CLOSED_PLANAR", square(6, 6, 9, 9, 2))]),
            ((2, "Marker", None), [("POINT", "8\\8\\1")]),
            ((3, "Line", "0\\255\\0"), [("OPEN_PLANAR", "1\\1\\0\\14\\14\\0"),
                                           ("CLOSED_PLANAR", square(1, 10, 5, 14, 3))])]
    rtstruct_file("three-rois.dcm", rois)
    # 40 ROIs of one square each, all overlapping: more label layers than the reader builds
    # (dicom_rtstruct.h: kMaxRoiLayers, 32): refused, not read at gigabytes.
    rtstruct_file("forty-overlapping-rois.dcm",
                  [((n, "ROI %d" % n, None), [("CLOSED_PLANAR", square(3, 3, 12, 12, 1))]) for n in range(1, 41)])


def rtstruct_file(name, rois):
    """An RT Structure Set of `rois` [((number, name, colour), [(kind, points)])] on the seed series."""
    rt_class = "1.2.840.10008.5.1.4.1.1.481.3"
    el = dcm_common("RTSTRUCT", rt_class, 8) + [
        ((0x3006, 0x0002), "SH", "fuzz"), ((0x3006, 0x0008), "DA", "20260101"), ((0x3006, 0x0009), "TM", "120000"),
        ((0x3006, 0x0010), "SQ", [[((0x0020, 0x0052), "UI", UID + "9"),
                                   ((0x3006, 0x0012), "SQ", [[((0x0008, 0x1150), "UI", "1.2.840.10008.3.1.2.3.1"),
                                                              ((0x0008, 0x1155), "UI", UID + "1"),
                                                              ((0x3006, 0x0014), "SQ", [[((0x0020, 0x000E), "UI", UID + "3.2")]])]])]]),
        ((0x3006, 0x0020), "SQ", [[((0x3006, 0x0022), "IS", str(n)), ((0x3006, 0x0024), "UI", UID + "9"),
                                   ((0x3006, 0x0026), "LO", name), ((0x3006, 0x0036), "CS", "MANUAL")]
                                  for (n, name, _), _ in rois]),
        ((0x3006, 0x0039), "SQ", [[((0x3006, 0x0084), "IS", str(n))] +
                                  ([((0x3006, 0x002A), "IS", color)] if color else []) +
                                  [((0x3006, 0x0040), "SQ", [[((0x3006, 0x0042), "CS", kind),
                                                              ((0x3006, 0x0046), "IS", str(len(data.split("\\")) // 3)),
                                                              ((0x3006, 0x0048), "IS", str(c + 1)),
                                                              ((0x3006, 0x0050), "DS", data)]
                                                             for c, (kind, data) in enumerate(contours)])]
                                  for (n, _, color), contours in rois]),
        ((0x3006, 0x0080), "SQ", [[((0x3006, 0x0082), "IS", str(n)), ((0x3006, 0x0084), "IS", str(n)),
                                   ((0x3006, 0x00A4), "CS", "ORGAN"), ((0x3006, 0x00A6), "PN", "")]
                                  for (n, _, _), _ in rois]),
    ]
    out("rtstruct", name, dcm_file(rt_class, UID + "8.1", el))


def pacs_seeds():
    study = [((0x0008, 0x0005), "CS", "ISO_IR 100"), ((0x0008, 0x0020), "DA", "20260101"),
             ((0x0008, 0x0030), "TM", "120000.5"), ((0x0008, 0x0050), "SH", "ACC1"),
             ((0x0008, 0x0052), "CS", "STUDY"), ((0x0008, 0x0061), "CS", "CT\\SEG"),
             ((0x0008, 0x1030), "LO", "Head"), ((0x0010, 0x0010), "PN", "Fuzz^Seed"),
             ((0x0010, 0x0020), "LO", "VH-FUZZ"), ((0x0010, 0x0030), "DA", "19700101"),
             ((0x0010, 0x0040), "CS", "O"), ((0x0020, 0x000D), "UI", UID + "1"),
             ((0x0020, 0x1206), "IS", "2")]
    series = [((0x0008, 0x0052), "CS", "SERIES"), ((0x0008, 0x0060), "CS", "CT"),
              ((0x0008, 0x103E), "LO", "Axial 1 mm"), ((0x0020, 0x000D), "UI", UID + "1"),
              ((0x0020, 0x000E), "UI", UID + "3.2"), ((0x0020, 0x0011), "IS", "3"),
              ((0x0020, 0x1209), "IS", "93")]
    out("pacs_response", "study-implicit", b"\0" + dcm_implicit(study))
    out("pacs_response", "series-implicit", b"\0" + dcm_implicit(series))
    out("pacs_response", "study-explicit", b"\1" + dcm_elements(study))
    out("pacs_response", "series-explicit-bad-numbers", b"\1" + dcm_elements(
        [el for el in series if el[0] not in ((0x0020, 0x0011), (0x0020, 0x1209))] +
        [((0x0020, 0x0011), "IS", " -4 "), ((0x0020, 0x1209), "IS", "1e9")]))


def igtl_message(msg_type, name, body, version=1):
    header = struct.pack(">H12s20sQQQ", version, msg_type.encode(), name.encode(), 0, len(body), 0)
    return header, body


def igtl_image_body(dims, scalar_type, voxels, endian=2, coord=1, components=1):
    """An IMAGE content (version-1 image header of 72 bytes, then the voxels): unit axes,
    spacing 1 mm, centre 0; endian 1 big, 2 little; coordinates 1 RAS, 2 LPS."""
    head = struct.pack(">HBBBB3H", 1, components, scalar_type, endian, coord, *dims)
    axes = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    head += struct.pack(">12f", *(axes + [0, 0, 0]))
    head += struct.pack(">3H3H", 0, 0, 0, *dims)
    return head + voxels


def igtl_seeds():
    # Mode byte 3: body size and CRC-64 set by the target (fuzz_igtl.cpp).
    dims = (4, 3, 2)
    n = dims[0] * dims[1] * dims[2]
    uint8 = igtl_image_body(dims, 3, bytes(range(n)))
    int16_be = igtl_image_body(dims, 4, struct.pack(">%dh" % n, *range(-n, n, 2)), endian=1, coord=2)
    float64 = igtl_image_body(dims, 11, struct.pack("<%dd" % n, *[0.5 * i for i in range(n)]))
    for name, body in (("image-uint8-ras", uint8), ("image-int16-bigendian-lps", int16_be),
                       ("image-float64", float64)):
        header, body = igtl_message("IMAGE", name, body)
        out("igtl", name, b"\3" + header + body)
    # Header version 2: extended header (12 bytes: its size, metadata header size, metadata size,
    # message id), the content, metadata (index entry: key size 2, encoding 2, value size 4).
    meta_header = struct.pack(">H", 1) + struct.pack(">HHI", 3, 3, 2)
    meta = b"key" + b"ok"
    ext = struct.pack(">HHII", 12, len(meta_header), len(meta), 7)
    header, body = igtl_message("IMAGE", "image-v2-metadata", ext + uint8 + meta_header + meta, version=2)
    out("igtl", "image-v2-metadata", b"\3" + header + body)
    header, body = igtl_message("TRANSFORM", "other-type", bytes(48))
    out("igtl", "transform", b"\3" + header + body)
    # The bounds on what an IMAGE may say: a byte order that is neither 1 nor 2, and spacings far
    # beyond a scan's (1e38 mm, finite) and below it (1e-30 mm): each refused naming the value.
    header, body = igtl_message("IMAGE", "endian-7", igtl_image_body(dims, 3, bytes(range(n)), endian=7))
    out("igtl", "image-endian-7", b"\3" + header + body)
    for label, spacing in (("1e38", 1e38), ("1e-30", 1e-30)):
        image = bytearray(igtl_image_body(dims, 3, bytes(range(n))))
        struct.pack_into(">3f", image, 12, spacing, 0, 0)  # the i axis scaled by the spacing
        header, body = igtl_message("IMAGE", "spacing-" + label, bytes(image))
        out("igtl", "image-spacing-" + label, b"\3" + header + body)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--datasets", default=str(ROOT.parent / "shared/datasets"))
    ap.add_argument("--recording")
    ap.add_argument("--trajectory")
    a = ap.parse_args()
    ds = pathlib.Path(a.datasets)
    dicom_seeds(ds)
    nrrd_seeds(ds)
    metaimage_seeds(ds)
    nifti_seeds(ds)
    mesh_seeds(ds)
    scene_seeds()
    trajectory_seeds(a.trajectory)
    recording_seeds(a.recording)
    device_seeds()
    seg_seed("binary-two-segments")
    seg_seed("fractional-overlapping", fractional=True, overlap=True)
    rtstruct_seeds()
    pacs_seeds()
    igtl_seeds()


if __name__ == "__main__":
    main()
