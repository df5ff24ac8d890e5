"""Scene.volume and Scene.affine_LPS_m of a DICOM series against nibabel's DICOM wrapper
(nibabel.nicom, Debian python3-nibabel with python3-pydicom): every pixel of the sampled slices,
put in the patient by nibabel's affine (LPS millimetres), lands on a voxel centre of ours, and
our value there is the pixel's stored value through its Rescale Slope and Intercept (read by
pydicom). The datasets are the shared folder's (skipped with a message when absent)."""
import os
import pathlib
import warnings

import numpy as np
import pytest

import volume_haptics as vh

pydicom = pytest.importorskip("pydicom", reason="python3-pydicom is not installed (packaging/setup.sh test installs it)")
dicomwrappers = pytest.importorskip("nibabel.nicom.dicomwrappers")

SHARED = pathlib.Path(os.environ.get("VH_SHARED_DATASETS_DIR",
                                     pathlib.Path(__file__).resolve().parents[4] / "shared/datasets"))


@pytest.mark.parametrize("series, every", [("ct/ct-head-small", 7), ("ct/philips-head-phantom-bone", 40)])
def test_every_pixel_lands_on_our_voxel_with_its_value(series, every):
    folder = SHARED / series
    if not folder.is_dir():
        pytest.skip("needs %s (the shared datasets)" % folder)
    files = sorted(p for p in folder.rglob("*") if p.is_file() and not p.name.startswith("."))
    scene = vh.load_scene({"volume": {"path": str(folder)}, "tool": {"mesh": "builtin:probe"}})
    volume = scene.volume
    to_index = np.linalg.inv(np.asarray(scene.affine_LPS_m))
    checked = 0
    for path in files[::every]:
        try:
            ds = pydicom.dcmread(str(path))
        except Exception:
            continue  # not a DICOM file (a DICOMDIR's neighbours, notes)
        if "PixelData" not in ds:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "the DICOM readers are highly experimental"
            wrapper = dicomwrappers.wrapper_from_data(ds)
            affine_mm = np.asarray(wrapper.affine)  # [row, column, 0, 1] -> patient LPS [mm]
        stored = ds.pixel_array.astype(np.float64)
        values = stored * float(ds.get("RescaleSlope", 1)) + float(ds.get("RescaleIntercept", 0))
        rows, cols = values.shape
        r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        points_mm = affine_mm @ np.stack([r.ravel(), c.ravel(), np.zeros(r.size), np.ones(r.size)])
        ijk = (to_index @ np.vstack([points_mm[:3] / 1000.0, np.ones(r.size)]))[:3]
        nearest = np.rint(ijk)
        assert np.abs(ijk - nearest).max() < 1e-3, "%s: pixels fall between our voxel centres" % path.name
        i, j, k = nearest.astype(int)
        inside = (i >= 0) & (i < volume.shape[0]) & (j >= 0) & (j < volume.shape[1]) & (k >= 0) & (k < volume.shape[2])
        assert inside.all(), "%s: pixels outside our grid" % path.name
        np.testing.assert_allclose(volume[i, j, k], values.ravel(), rtol=0, atol=1e-3, err_msg=path.name)
        checked += 1
    assert checked >= 3, "too few slices checked in %s" % folder
