"""Input.affine (RAS, as nibabel gives it), hpcm.from_nibabel and hpcm.to_nibabel (issue 32,
item 5), checked against nibabel on the abdomen NIfTI, a permuted and flipped copy made by
nibabel, and against pydicom on the DICOM series."""
import os
import pathlib

import numpy as np
import pytest

import hpcm

nib = pytest.importorskip("nibabel")

DATA = pathlib.Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
NIFTI = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
DICOM = DATA / "abdomen-ct-dicom"
pytestmark = [pytest.mark.skipif(not hpcm.has_io, reason="hpcm built without ITK"),
              pytest.mark.skipif(not NIFTI.exists(), reason=f"{NIFTI} not present")]


def reoriented_copy(tmp_path):
    """The abdomen CT with its axes permuted and two flipped (nibabel's own reorientation), saved."""
    img = nib.load(NIFTI)
    now = nib.orientations.io_orientation(img.affine)
    wanted = nib.orientations.axcodes2ornt(("S", "L", "P"))
    copy = img.as_reoriented(nib.orientations.ornt_transform(now, wanted))
    path = tmp_path / "slp.nii.gz"
    nib.save(copy, path)
    return nib.load(path), path


def test_input_affine_is_nibabels_affine_for_the_nifti_and_a_permuted_flipped_copy(tmp_path):
    img = nib.load(NIFTI)
    inp = hpcm.load_input(NIFTI, downsample=2)
    np.testing.assert_allclose(inp.affine, img.affine, atol=1e-4)
    copy, path = reoriented_copy(tmp_path)
    assert nib.aff2axcodes(copy.affine) == ("S", "L", "P")
    inp_copy = hpcm.load_input(path)
    np.testing.assert_allclose(inp_copy.affine, copy.affine, atol=1e-4)
    # The same anatomy: both lattices (LPS order) hold the same HU at the same place.
    a, b = hpcm.load_input(NIFTI).lattice, inp_copy.lattice
    np.testing.assert_allclose(b.origin, a.origin, atol=1e-3)
    np.testing.assert_allclose(b.hu, a.hu, atol=1e-3)


def test_lattice_affine_is_the_block_mean_grid():
    inp = hpcm.load_input(NIFTI, downsample=2)
    a, s = inp.lattice_affine, inp.affine
    np.testing.assert_allclose(a[:3, :3], 2 * s[:3, :3], atol=1e-4)
    np.testing.assert_allclose(a[:3, 3], s[:3, :3] @ [0.5, 0.5, 0.5] + s[:3, 3], atol=1e-4)  # block centre


def test_input_affine_of_the_dicom_series_matches_its_headers_at_downsample_4():
    pydicom = pytest.importorskip("pydicom")
    if not DICOM.exists():
        pytest.skip(f"{DICOM} not present")
    inp = hpcm.load_input(DICOM, downsample=4)
    slices = [pydicom.dcmread(f) for f in sorted(DICOM.iterdir())]
    stored = np.asarray(inp.stored.hu)
    assert stored.shape == (slices[0].Columns, slices[0].Rows, len(slices))
    ras_to_lps = np.diag([-1.0, -1.0, 1.0])
    row, col = np.array(slices[0].ImageOrientationPatient[:3], float), np.array(slices[0].ImageOrientationPatient[3:], float)
    dy, dx = (float(v) for v in slices[0].PixelSpacing)  # row spacing, column spacing
    lps = ras_to_lps @ inp.affine[:3, :]
    np.testing.assert_allclose(lps[:, 0], row * dx, atol=1e-4)  # i runs along a row
    np.testing.assert_allclose(lps[:, 1], col * dy, atol=1e-4)
    by_position = {tuple(np.round(np.array(s.ImagePositionPatient, float), 2)): s for s in slices}
    for k in (0, len(slices) // 2, len(slices) - 1):
        # The slice the affine puts at index k is the file with that ImagePositionPatient...
        where = tuple(np.round(lps @ [0, 0, k, 1], 2))
        assert where in by_position, f"slice {k} at LPS {where}: no DICOM file there"
        s = by_position[where]
        # ... and holds that file's HU (pixel [row j, column i] is voxel [i, j]).
        hu = s.pixel_array.astype(float) * float(s.RescaleSlope) + float(s.RescaleIntercept)
        np.testing.assert_allclose(stored[:, :, k], hu.T, atol=0.5)


def test_from_nibabel_reads_ras_as_ras(tmp_path):
    copy, _ = reoriented_copy(tmp_path)
    inp = hpcm.from_nibabel(copy)
    np.testing.assert_allclose(inp.affine, copy.affine, atol=1e-4)
    ref = hpcm.load_input(NIFTI)
    # Front stays front: the same LPS lattice as the file read by ITK (at downsample 1: blocks
    # are formed in each file's own index order, so the voxels left out differ between them).
    assert inp.lattice.dims == ref.lattice.dims
    np.testing.assert_allclose(inp.lattice.origin, ref.lattice.origin, atol=1e-3)
    np.testing.assert_allclose(inp.lattice.direction, ref.lattice.direction, atol=1e-6)
    np.testing.assert_allclose(inp.lattice.hu, ref.lattice.hu, atol=1e-2)
    assert hpcm.from_nibabel(copy, downsample=2).lattice.dims == hpcm.load_input(NIFTI, downsample=2).lattice.dims


def test_from_nibabel_refuses_what_is_not_one_ct_volume():
    with pytest.raises(hpcm.Error, match="3-D"):
        hpcm.from_nibabel(nib.Nifti1Image(np.zeros((4, 4, 4, 2), np.float32), np.eye(4)))
    sheared = np.eye(4)
    sheared[0, 1] = 0.5
    with pytest.raises(hpcm.Error, match="orthogonal"):
        hpcm.from_nibabel(nib.Nifti1Image(np.zeros((8, 8, 8), np.float32), sheared))


def test_to_nibabel_round_trips_and_places_arrays_on_the_inputs_grids(tmp_path):
    inp = hpcm.load_input(NIFTI, downsample=2)
    img = hpcm.to_nibabel(inp.stored)
    np.testing.assert_allclose(img.affine, nib.load(NIFTI).affine, atol=1e-4)
    np.testing.assert_allclose(img.get_fdata(), nib.load(NIFTI).get_fdata(), atol=1e-2)
    back = hpcm.from_nibabel(img)
    np.testing.assert_allclose(back.affine, inp.affine, atol=1e-6)
    sim = hpcm.Simulation(inp.lattice)
    u = hpcm.displacement_mm(inp, sim)  # on inp.lattice_grid
    field = hpcm.to_nibabel(u, like=inp)
    np.testing.assert_allclose(field.affine, inp.lattice_affine, atol=1e-6)
    assert field.shape == u.shape[:3] + (1, 3)
    assert field.header.get_intent()[0] == "vector"
    v = hpcm.pullback_mm(inp, sim)  # on inp.stored's grid
    np.testing.assert_allclose(hpcm.to_nibabel(v, like=inp).affine, inp.affine, atol=1e-6)
    with pytest.raises(hpcm.Error, match="grid"):
        hpcm.to_nibabel(np.zeros((3, 3, 3), np.float32), like=inp)
