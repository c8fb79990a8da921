"""hpcm.warp_labels and hpcm.pullback_mm (issue 32, items 1 and 3): a label map of the abdomen
CT's whole grid, an roi input (the map is cropped like the CT), checked with nibabel/numpy."""
import os
from pathlib import Path

import numpy as np
import pytest

import hpcm

DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
NIFTI = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
ROI = (0, 0, 10, 122, 101, 90)

pytestmark = [
    pytest.mark.skipif(not hpcm.has_io, reason="hpcm was built without ITK"),
    pytest.mark.skipif(not NIFTI.is_file(), reason=f"{NIFTI} is absent (../shared/data)"),
]


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    nib = pytest.importorskip("nibabel")
    tmp = tmp_path_factory.mktemp("warp")
    src = nib.load(str(NIFTI))
    hu = np.asarray(src.dataobj)
    labels = np.zeros(hu.shape, dtype=np.int16)
    labels[hu >= -500] = 5
    labels[hu >= 25] = 300
    labels[hu >= 375] = -7
    path = tmp / "organs.nii.gz"
    nib.save(nib.Nifti1Image(labels, src.affine), str(path))
    inp = hpcm.load_input(str(NIFTI), downsample=2, roi=ROI)
    sim = hpcm.Simulation(inp.lattice, hpcm.Params())
    sim.grab("auto")
    for f in range(6):
        sim.move_tool((0.0, -0.25 * (f + 1), 0.0))
        sim.step()
    cropped = labels[ROI[0]:ROI[3], ROI[1]:ROI[4], ROI[2]:ROI[5]]
    return nib, tmp, src, labels, path, inp, sim, cropped


def test_warp_labels_moves_labels_and_invents_none(case):
    nib, tmp, src, labels, path, inp, sim, cropped = case
    out = tmp / "warped.nii.gz"
    warped = hpcm.warp_labels(inp, sim, str(path), path=str(out))
    assert warped.dtype == np.int16 and warped.shape == cropped.shape
    assert set(np.unique(warped)) <= set(np.unique(cropped)), "a label was invented"
    v = hpcm.pullback_mm(inp, sim)
    assert v.shape == cropped.shape + (3,)
    still = np.all(v == 0, axis=-1)
    assert 0.05 < still.mean() < 1.0, f"{still.mean():.1%} of the voxels still: the check would be weak"
    np.testing.assert_array_equal(warped[still], cropped[still])
    assert np.any(warped[~still] != cropped[~still]), "no label moved"
    written = nib.load(str(out))
    np.testing.assert_array_equal(np.asarray(written.dataobj), warped)
    assert np.asarray(written.dataobj).dtype == np.int16
    expected = src.affine.copy()
    expected[:3, 3] = src.affine[:3, :3] @ ROI[:3] + src.affine[:3, 3]
    np.testing.assert_allclose(written.affine, expected, atol=1e-3)


def test_pullback_matches_the_export(case):
    nib, tmp, src, labels, path, inp, sim, cropped = case
    files = hpcm.export_frame(inp, sim, str(tmp))
    assert Path(files["pullback_nifti"]).name == "displacement_pullback_final.nii.gz"
    written = np.asarray(nib.load(files["pullback_nifti"]).dataobj)[:, :, :, 0, :]
    np.testing.assert_array_equal(written, hpcm.pullback_mm(inp, sim))
    assert Path(files["labels_deformed"]).is_file()


def test_bad_label_maps_raise(case, tmp_path):
    nib, tmp, src, labels, path, inp, sim, cropped = case
    as_float = tmp_path / "float.nii.gz"
    nib.save(nib.Nifti1Image(labels.astype(np.float32), src.affine), str(as_float))
    with pytest.raises(hpcm.Error, match="integer"):
        hpcm.warp_labels(inp, sim, str(as_float))
    other = tmp_path / "other.nii.gz"
    nib.save(nib.Nifti1Image(labels[:, :, :50], src.affine), str(other))
    with pytest.raises(hpcm.Error, match=r"label map 122x101x50 voxels.*input \(cropped to the roi\) 122x101x80 voxels"):
        hpcm.warp_labels(inp, sim, str(other))
