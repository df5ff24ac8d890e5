#!/usr/bin/python3
"""Writes NIfTI test files with nibabel (an independent reader and writer) and, for each, where
nibabel places a few of its voxels: expected.json, read by nifti_test.cpp.

    nifti_fixtures.py OUT_DIR

For every file: the shape, the voxel sizes along i, j, k [m], and samples: file voxel (i, j, k),
its centre in patient LPS [m] (nibabel's affine, RAS+ in the file's unit, converted:
x_LPS = -x_RAS, y_LPS = -y_RAS, scaled by the unit of xyzt_units) and its value as nibabel reads
it (scl_slope / scl_inter applied; the first volume of a 4-D file). The voxels hold
1 + i + 10 j + 100 k (scaled where the file scales), so a voxel found at the wrong place shows.
Exit status 77 when nibabel or numpy is missing.
"""
import json
import math
import pathlib
import sys

try:
    import nibabel as nib
    import numpy as np
except ImportError as e:  # pragma: no cover
    print("nibabel / numpy missing:", e)
    sys.exit(77)

UNIT_TO_M = {"meter": 1.0, "mm": 1e-3, "micron": 1e-6, "unknown": 1e-3}


def rotation(axis, degrees):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    a = math.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * k @ k


def affine(R, zooms, offset):
    A = np.eye(4)
    A[:3, :3] = R @ np.diag(zooms)
    A[:3, 3] = offset
    return A


def ramp(shape, dtype):
    i, j, k = np.meshgrid(*[np.arange(n) for n in shape[:3]], indexing="ij")
    v = 1 + i + 10 * j + 100 * k
    if len(shape) == 4:
        v = np.stack([v + 1000 * t for t in range(shape[3])], axis=3)
    return v.astype(dtype)


def samples(img, A, unit):
    """Sample voxels of `img` placed by the 4 x 4 affine `A` (file unit)."""
    data = np.asarray(img.dataobj, dtype=np.float64)  # nibabel applies scl_slope / scl_inter
    nx, ny, nz = img.shape[:3]
    out = []
    for ijk in [(0, 0, 0), (nx - 1, 0, 0), (0, ny - 1, 0), (0, 0, nz - 1), (nx - 1, ny - 1, nz - 1), (3, 2, 1)]:
        ras = A @ np.array([*ijk, 1.0])
        lps_m = [-ras[0] * UNIT_TO_M[unit], -ras[1] * UNIT_TO_M[unit], ras[2] * UNIT_TO_M[unit]]
        value = data[ijk] if data.ndim == 3 else data[ijk + (0,)]
        out.append({"ijk": list(ijk), "p_LPS_m": lps_m, "value": float(value)})
    return out


def entry(name, img, A, unit, **extra):
    zooms_m = [float(np.linalg.norm(A[:3, c])) * UNIT_TO_M[unit] for c in range(3)]
    e = {"file": name, "shape": list(img.shape[:3]), "spacing_m": zooms_m, "samples": samples(img, A, unit)}
    e.update(extra)
    return e


def main():
    out = pathlib.Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    cases = []

    # 1. Oblique sform (sform_code 1) beside a different qform: the sform wins (nibabel's affine).
    R = rotation([1, 2, 3], 25)
    A = affine(R, [0.8, 1.2, 2.5], [-40.0, 12.5, 30.0])
    img = nib.Nifti1Image(ramp((7, 6, 5), np.float32), None)
    img.set_qform(affine(np.eye(3), [0.8, 1.2, 2.5], [1, 2, 3]), code=1)
    img.set_sform(A, code=2)
    img.header.set_xyzt_units("mm", "sec")
    nib.save(img, out / "oblique_sform.nii.gz")
    img = nib.load(out / "oblique_sform.nii.gz")
    assert np.allclose(img.affine, A, atol=1e-4)
    cases.append(entry("oblique_sform.nii.gz", img, img.affine, "mm", format="NIfTI-1"))

    # 2. qform only, every axis reversed (determinant < 0: qfac = -1), int16.
    R = rotation([0, 0, 1], 10) @ np.diag([-1.0, -1.0, -1.0])
    A = affine(R, [1.5, 0.75, 3.0], [60.0, -20.0, -45.0])
    img = nib.Nifti1Image(ramp((7, 6, 5), np.int16), None)
    img.set_qform(A, code=1)
    img.set_sform(None, code=0)
    img.header.set_xyzt_units("mm")
    nib.save(img, out / "flipped_qform.nii")
    img = nib.load(out / "flipped_qform.nii")
    assert img.header["sform_code"] == 0 and img.header["pixdim"][0] == -1
    cases.append(entry("flipped_qform.nii", img, img.affine, "mm", format="NIfTI-1"))

    # 3. Scaled values (scl_slope, scl_inter chosen by nibabel to fit int16) in micrometres; an
    #    sform alone whose determinant is negative (x reversed: VTK reverses the slice order).
    A = affine(np.diag([-1.0, 1.0, 1.0]), [50.0, 50.0, 80.0], [100.0, 200.0, -300.0])
    values = ramp((7, 6, 5), np.float64) * 300.25 - 5000.5  # a span over int16's: scaled
    img = nib.Nifti1Image(values, None)
    img.set_sform(A, code=1)
    img.set_qform(None, code=0)
    img.set_data_dtype(np.int16)
    img.header.set_xyzt_units("micron")
    nib.save(img, out / "scaled_micron.nii")
    img = nib.load(out / "scaled_micron.nii")
    assert img.dataobj.slope != 1.0 and img.dataobj.inter != 0.0  # the file's scl_slope / scl_inter
    cases.append(entry("scaled_micron.nii", img, img.affine, "micron", format="NIfTI-1"))

    # 4. NIfTI-2, uint16, oblique sform, in metres.
    R = rotation([-2, 1, 0.5], 40)
    A = affine(R, [0.0005, 0.0007, 0.001], [0.01, -0.02, 0.03])
    img = nib.Nifti2Image(ramp((7, 6, 5), np.uint16), None)
    img.set_sform(A, code=1)
    img.set_qform(None, code=0)
    img.header.set_xyzt_units("meter")
    nib.save(img, out / "nifti2.nii")
    img = nib.load(out / "nifti2.nii")
    cases.append(entry("nifti2.nii", img, img.affine, "meter", format="NIfTI-2"))

    # 5. A .hdr/.img pair, big-endian (header and int16 voxels), qform and sform equal.
    R = rotation([0, 1, 0], -15)
    A = affine(R, [2.0, 1.0, 1.25], [5.0, 6.0, 7.0])
    img = nib.Nifti1Pair(ramp((7, 6, 5), np.int16), None)
    img.set_qform(A, code=1)
    img.set_sform(A, code=1)
    img.header.set_xyzt_units("mm")
    big = img.header.as_byteswapped(">")
    with open(out / "pair.hdr", "wb") as f:
        big.write_to(f)
    (out / "pair.img").write_bytes(np.asarray(img.dataobj).astype(">i2").tobytes(order="F"))
    img = nib.load(out / "pair.hdr")
    assert img.header.endianness == ">" and img.header["magic"] == b"ni1"
    cases.append(entry("pair.hdr", img, img.affine, "mm", format="NIfTI-1"))

    # 6. Neither form (both codes 0): the NIfTI-1 standard's method 1, x = pixdim[1] i, ...
    #    (nibabel's own affine for this case is Analyze's, centred and flipped: not used).
    img = nib.Nifti1Image(ramp((7, 6, 5), np.int16), None)
    img.header.set_zooms((0.9, 1.1, 2.0))
    img.set_qform(None, code=0)
    img.set_sform(None, code=0)
    img.header.set_xyzt_units("mm")
    nib.save(img, out / "no_form.nii")
    img = nib.load(out / "no_form.nii")
    zooms = img.header.get_zooms()[:3]
    method1 = affine(np.eye(3), zooms, [0, 0, 0])
    cases.append(entry("no_form.nii", img, method1, "mm", format="NIfTI-1", notice="neither an sform nor a qform"))

    # 7. A sheared sform beside a valid qform: the grid follows the qform (as ITK).
    Q = affine(rotation([1, 0, 0], 30), [1.0, 1.0, 2.0], [-3.0, 4.0, 5.0])
    S = Q.copy()
    S[0, 1] += 0.4
    img = nib.Nifti1Image(ramp((7, 6, 5), np.int16), None)
    img.set_qform(Q, code=1)
    img.set_sform(S, code=1)
    img.header.set_xyzt_units("mm")
    nib.save(img, out / "sheared_sform.nii")
    img = nib.load(out / "sheared_sform.nii")
    cases.append(entry("sheared_sform.nii", img, img.get_qform(), "mm", format="NIfTI-1", notice="sheared"))

    # 8. 4-D: the first volume, with a notice.
    A = affine(np.eye(3), [1.0, 1.0, 1.0], [0, 0, 0])
    img = nib.Nifti1Image(ramp((7, 6, 5, 3), np.int16), A)
    img.header.set_xyzt_units("mm", "sec")
    nib.save(img, out / "series4d.nii.gz")
    img = nib.load(out / "series4d.nii.gz")
    cases.append(entry("series4d.nii.gz", img, img.affine, "mm", format="NIfTI-1", notice="4-D NIfTI of 3 volumes"))

    # 9. A label map (intent NIFTI_INTENT_LABEL), uint8, labels 0, 1, 2, 5, oblique sform.
    labels = np.zeros((8, 7, 6), np.uint8)
    labels[1:4, 1:3, 1:3] = 1
    labels[4:7, 3:6, 2:5] = 2
    labels[0, 6, 5] = 5
    A = affine(rotation([1, 1, 0], 20), [0.7, 0.7, 1.5], [-10.0, -20.0, 15.0])
    img = nib.Nifti1Image(labels, None)
    img.set_sform(A, code=1)
    img.set_qform(A, code=1)
    img.header.set_intent("label")
    img.header.set_xyzt_units("mm")
    nib.save(img, out / "labels.nii.gz")
    img = nib.load(out / "labels.nii.gz")
    e = entry("labels.nii.gz", img, img.affine, "mm", format="NIfTI-1")
    e["samples"] += [
        {"ijk": [2, 1, 1], "p_LPS_m": None, "value": 1.0},
        {"ijk": [5, 4, 3], "p_LPS_m": None, "value": 2.0},
        {"ijk": [0, 6, 5], "p_LPS_m": None, "value": 5.0},
    ]
    for s in e["samples"]:
        ras = img.affine @ np.array([*s["ijk"], 1.0])
        s["p_LPS_m"] = [-ras[0] * 1e-3, -ras[1] * 1e-3, ras[2] * 1e-3]
        s["value"] = float(labels[tuple(s["ijk"])])
    e["labels"] = {str(v): int((labels == v).sum()) for v in (1, 2, 5)}
    cases.append(e)

    (out / "expected.json").write_text(json.dumps({"nibabel": nib.__version__, "cases": cases}, indent=1))


if __name__ == "__main__":
    main()
