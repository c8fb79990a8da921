"""Deformed labels (--warp-labels, labels_deformed_<tag>) and the pull-back field
(displacement_pullback_<tag>) of `hpcm run --export`, checked with nibabel, numpy, scipy and
plastimatch (issue 32, items 1 and 3).

Run by CTest (io_labels_pullback) as
  /usr/bin/python3 -m pytest tests/io/test_labels_pullback.py
with HPCM_CLI and HPCM_SHARED_DATA in the environment; exits 77 (skipped) without the shared
CT data (conftest.py).
"""
import os
import shlex
import subprocess
from pathlib import Path

import numpy as np
import pytest

nib = pytest.importorskip("nibabel")

from test_exports_tools import (DICOM, HPCM, NIFTI, PLASTIMATCH, classes, dicom_series_by_pydicom, load,
                                needs_plastimatch, scenario, still_voxels)

DOCS = Path(__file__).resolve().parents[2] / "docs"

# The pull-back recipe of docs/slicer.md and docs/io.md, run here exactly as written (the test
# checks that both documents hold this line).
# plastimatch 1.9 warps float (or int16) images only, hence the first line for an int32 CT.
PLASTIMATCH_RECIPE = [
    "plastimatch convert --input ct.nii.gz --output-type float --output-img ct_float.nii.gz",
    "plastimatch convert --input ct_float.nii.gz --xf displacement_pullback_final.nii.gz "
    "--output-img warped.nii.gz --interpolation linear --default-value -1000",
]
# The recipe must reproduce hpcm's deformed CT within 1 % (rms) of the change the deformation made.
RECIPE_TOLERANCE = 0.01


def run_hpcm(tmp, volume, *options, pull=3.0, frames=10, check=True):
    out = tmp / "export"
    cmd = [HPCM, "run", "--input", str(volume), "--scenario", str(scenario(tmp / "pull.toml", pull, frames)),
           "--out", str(tmp / "run"), "--export", str(out), *map(str, options)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if check:
        assert r.returncode == 0, f"{cmd}: {r.stderr}"
    return out, r


def multi_label_map(hu, dtype):
    """A segmentation made from the CT's thresholds, with labels that are not 0..3 (and a few of
    the type's extremes) so that an invented or mixed label would show."""
    labels = np.zeros(hu.shape, dtype=dtype)
    labels[hu >= -500] = 7       # body
    labels[hu >= 25] = 120       # muscle / organ
    labels[hu >= 375] = np.iinfo(dtype).max  # bone
    labels[(hu >= -100) & (hu < 25)] = 33  # fat
    return labels


def lattice_nearest(labels_coarse, shape, f):
    """The coarse class map sampled by nearest lattice node at every input voxel (0 beyond half a
    node outside the lattice), as the deformed class labels are where nothing moved."""
    idx = []
    for axis in range(3):
        q = (np.arange(shape[axis]) - (f - 1) / 2.0) / f
        n = labels_coarse.shape[axis]
        k = np.floor(q + 0.5).astype(int)
        idx.append(np.where((q >= -0.5) & (q <= n - 0.5), np.clip(k, 0, n - 1), -1))
    out = labels_coarse[np.ix_(np.clip(idx[0], 0, None), np.clip(idx[1], 0, None), np.clip(idx[2], 0, None))]
    outside = (idx[0][:, None, None] < 0) | (idx[1][None, :, None] < 0) | (idx[2][None, None, :] < 0)
    return np.where(outside, 0, out)


def check_warped(out, label_path, labels, affine, f, tag="final"):
    """Checks of one warped label map against the undeformed one; returns the still voxels."""
    name = label_path.name.replace(".nii.gz", "")
    img, warped = load(out / f"warped_{name}_{tag}.nii.gz")
    assert warped.dtype == labels.dtype, f"warped map is {warped.dtype}, input {labels.dtype}"
    assert img.shape == labels.shape and np.allclose(img.affine, affine, atol=1e-3)
    invented = set(np.unique(warped)) - set(np.unique(labels))
    assert not invented, f"labels {sorted(invented)} appear in the warped map but not in the input"
    u = np.asarray(nib.load(str(out / f"displacement_{tag}.nii.gz")).dataobj)[:, :, :, 0, :]
    moved = np.any(u != 0, axis=-1)
    assert moved.any(), "nothing moved: the checks would be void"
    still = still_voxels(moved, labels.shape, f)
    assert still.mean() > 0.05
    np.testing.assert_array_equal(warped[still], labels[still], err_msg="labels changed where nothing moved")
    assert np.any(warped[~still] != labels[~still]), "no label moved where the tissue moved"
    for value in np.unique(labels):
        before = np.count_nonzero(labels == value)
        after = np.count_nonzero(warped == value)
        if before >= 1000:  # small labels: a few boundary voxels are more than 2 %
            assert abs(after - before) <= 0.02 * before, f"label {value}: {before} voxels before, {after} after"
    return warped, still


MET_TYPES = {"MET_SHORT": np.int16, "MET_UCHAR": np.uint8}


def write_mha(path, labels, affine_ras):
    """A MetaImage label map (LPS header) by hand: nibabel does not write MetaImage."""
    lps = np.diag([-1.0, -1.0, 1.0]) @ affine_ras[:3, :3]
    spacing = np.linalg.norm(lps, axis=0)
    direction = lps / spacing  # column a = direction of index axis a
    origin = np.diag([-1.0, -1.0, 1.0]) @ affine_ras[:3, 3]
    met = {v: k for k, v in MET_TYPES.items()}[labels.dtype.type]
    header = (f"ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
              f"CompressedData = False\nTransformMatrix = {' '.join(map(str, direction.T.ravel()))}\n"
              f"Offset = {' '.join(map(str, origin))}\nElementSpacing = {' '.join(map(str, spacing))}\n"
              f"DimSize = {' '.join(map(str, labels.shape))}\nElementType = {met}\nElementDataFile = LOCAL\n")
    path.write_bytes(header.encode() + labels.astype(labels.dtype.newbyteorder("<")).tobytes(order="F"))


def read_mha(path):
    """Type and values of a MetaImage file with its data inline (zlib-compressed or raw)."""
    import zlib
    raw = path.read_bytes()
    end = raw.index(b"ElementDataFile = LOCAL\n") + len(b"ElementDataFile = LOCAL\n")
    fields = dict(line.split(" = ", 1) for line in raw[:end].decode().splitlines())
    data = raw[end:]
    if fields.get("CompressedData") == "True":
        data = zlib.decompress(data)
    shape = tuple(int(v) for v in fields["DimSize"].split())
    return np.frombuffer(data, dtype=MET_TYPES[fields["ElementType"]]).reshape(shape, order="F")


@pytest.fixture(scope="module")
def abdomen(tmp_path_factory):
    """The abdomen CT at --downsample 2 with a multi-label int16 map and a uint8 mask warped."""
    tmp = tmp_path_factory.mktemp("labels")
    img = nib.load(str(NIFTI))
    hu = np.asarray(img.dataobj).astype(np.float64)
    organs = multi_label_map(hu, np.int16)
    organs_path = tmp / "organs.nii.gz"
    nib.save(nib.Nifti1Image(organs, img.affine), str(organs_path))
    mask = (hu >= 25).astype(np.uint8)
    mask_path = tmp / "mask.nii.gz"
    nib.save(nib.Nifti1Image(mask, img.affine), str(mask_path))
    write_mha(tmp / "organs_mha.mha", organs, img.affine)
    # --downsample 2: at 4 the pull moves every node of the small lattice a little, and the check
    # "identical to the input where nothing moved" would have no voxels to look at.
    out, _ = run_hpcm(tmp, NIFTI, "--downsample", 2, "--export-every", 5, "--warp-labels", organs_path,
                      "--warp-labels", mask_path, "--warp-labels", tmp / "organs_mha.mha", pull=1.0)
    return tmp, img, hu, organs, organs_path, mask, mask_path, out


def test_warped_labels_abdomen(abdomen):
    tmp, img, hu, organs, organs_path, mask, mask_path, out = abdomen
    check_warped(out, organs_path, organs, img.affine, 2)
    check_warped(out, mask_path, mask, img.affine, 2)
    # A MetaImage label map comes back as MetaImage, same type, the same labels as the NIfTI's.
    mha = read_mha(out / "warped_organs_mha_final.mha")
    assert mha.dtype == np.int16
    np.testing.assert_array_equal(mha, np.asarray(nib.load(str(out / "warped_organs_final.nii.gz")).dataobj))
    # Every --export-every tag gets its own warped copy; the final one is the last frame's.
    check_warped(out, organs_path, organs, img.affine, 2, tag="0005")
    assert (out / "warped_organs_0010.nii.gz").is_file()


def test_deformed_class_labels(abdomen):
    tmp, img, hu, organs, organs_path, mask, mask_path, out = abdomen
    coarse = np.asarray(nib.load(str(out / "labels.nii.gz")).dataobj)
    dimg, deformed = load(out / "labels_deformed_final.nii.gz")
    assert deformed.dtype == np.uint8 and dimg.shape == hu.shape and np.allclose(dimg.affine, img.affine, atol=1e-3)
    assert (out / "labels_deformed_final.ctbl").is_file()
    assert set(np.unique(deformed)) <= set(np.unique(coarse)) | {0}, "a class was invented"
    u = np.asarray(nib.load(str(out / "displacement_final.nii.gz")).dataobj)[:, :, :, 0, :]
    still = still_voxels(np.any(u != 0, axis=-1), hu.shape, 2)
    expected = lattice_nearest(coarse, hu.shape, 2)
    np.testing.assert_array_equal(deformed[still], expected[still])
    assert np.any(deformed[~still] != expected[~still]), "the class labels did not move"


def test_export_json_names_the_new_files(abdomen):
    import json
    out = abdomen[-1]
    side = json.loads((out / "export.json").read_text())
    final = side["exports"][-1]
    by_name = {f["file"]: f for f in final["files"]}
    assert "pull-back" in by_name["displacement_pullback_final.nii.gz"]["content"]
    assert "NOT the forward field" in by_name["displacement_pullback_final.nrrd"]["content"]
    assert by_name["displacement_final.nii.gz"]["content"].startswith("forward")
    assert by_name["labels_deformed_final.nii.gz"]["shape"] == list(abdomen[2].shape)
    assert by_name["warped_organs_final.nii.gz"]["source"].endswith("organs.nii.gz")
    assert by_name["warped_mask_final.nii.gz"]["source"].endswith("mask.nii.gz")


def test_float_and_non_integer_label_maps_are_refused(abdomen, tmp_path):
    img, organs = abdomen[1], abdomen[3]
    for dtype in (np.float32, np.float64):
        path = tmp_path / f"labels_{np.dtype(dtype).name}.nii.gz"
        nib.save(nib.Nifti1Image(organs.astype(dtype), img.affine), str(path))
        _, r = run_hpcm(tmp_path, NIFTI, "--downsample", 4, "--warp-labels", path, check=False)
        assert r.returncode != 0 and str(path) in r.stderr and "integer" in r.stderr, r.stderr
        assert not (tmp_path / "export").exists(), "the run started before the label map was refused"
    # Integer voxels scaled by scl_slope are not integer labels either.
    scaled = nib.Nifti1Image(organs, img.affine)
    scaled.header.set_slope_inter(0.5, 0)
    path = tmp_path / "scaled.nii.gz"
    nib.save(scaled, str(path))
    _, r = run_hpcm(tmp_path, NIFTI, "--downsample", 4, "--warp-labels", path, check=False)
    assert r.returncode != 0 and "scl_slope" in r.stderr, r.stderr


def test_label_map_on_another_grid_is_refused(abdomen, tmp_path):
    img, organs = abdomen[1], abdomen[3]
    cases = {
        "cropped": nib.Nifti1Image(organs[:-1], img.affine),
        "shifted": nib.Nifti1Image(organs, img.affine @ np.array([[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0],
                                                                   [0, 0, 0, 1.0]])),
    }
    for name, limg in cases.items():
        path = tmp_path / f"{name}.nii.gz"
        nib.save(limg, str(path))
        _, r = run_hpcm(tmp_path, NIFTI, "--downsample", 4, "--warp-labels", path, check=False)
        assert r.returncode != 0, f"{name}: accepted"
        # Both grids named: the label map's and the input's.
        shape = "x".join(map(str, limg.shape))
        assert str(path) in r.stderr and f"label map {shape} voxels" in r.stderr, r.stderr
        assert "input " + "x".join(map(str, organs.shape)) + " voxels" in r.stderr, r.stderr
        assert not (tmp_path / "export").exists()


def test_warp_labels_needs_export(tmp_path):
    r = subprocess.run([HPCM, "run", "--phantom", "24,24,16", "--frames", "2", "--out", str(tmp_path / "o"),
                        "--warp-labels", str(tmp_path / "x.nii.gz")], capture_output=True, text=True)
    assert r.returncode != 0 and "--warp-labels needs --export" in r.stderr, r.stderr


def test_warped_labels_dicom_series(tmp_path):
    hu, affine = dicom_series_by_pydicom()
    labels = multi_label_map(hu, np.uint16)
    path = tmp_path / "dicom_labels.nii.gz"
    nib.save(nib.Nifti1Image(labels, affine), str(path))
    out, _ = run_hpcm(tmp_path, DICOM, "--downsample", 4, "--warp-labels", path, pull=1.5, frames=5)
    check_warped(out, path, labels, affine, 4)
    dimg = nib.load(str(out / "labels_deformed_final.nii.gz"))
    assert dimg.shape == hu.shape and np.allclose(dimg.affine, affine, atol=1e-3)


# ---- the pull-back field ----------------------------------------------------------------------
def pullback_residual_mm(out, f, affine, shape):
    """|v(x) + u(x + v(x))| at every voxel: how well the pull-back field inverts the forward field
    (u trilinear on its lattice grid, scipy), in millimetres."""
    from scipy.ndimage import map_coordinates
    v = np.asarray(nib.load(str(out / "displacement_pullback_final.nii.gz")).dataobj)[:, :, :, 0, :].astype(np.float64)
    fimg = nib.load(str(out / "displacement_final.nii.gz"))
    u = np.asarray(fimg.dataobj)[:, :, :, 0, :].astype(np.float64)
    ras = np.diag([-1.0, -1.0, 1.0])  # the files' components are LPS; affines are RAS
    grid = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), axis=-1).reshape(-1, 3)
    x_ras = grid @ affine[:3, :3].T + affine[:3, 3]
    rest_ras = x_ras + v.reshape(-1, 3) @ ras.T
    inv = np.linalg.inv(fimg.affine)
    q = rest_ras @ inv[:3, :3].T + inv[:3, 3]  # continuous index of the lattice grid
    inside = np.all((q >= 0) & (q <= np.array(u.shape[:3]) - 1), axis=1)
    u_at = np.stack([map_coordinates(u[..., c], q[inside].T, order=1) for c in range(3)], axis=1)
    return np.linalg.norm(v.reshape(-1, 3)[inside] + u_at, axis=1), inside.mean()


@pytest.mark.parametrize("f", [2, 4])
def test_pullback_field_inverts_the_forward_field(f, tmp_path):
    img = nib.load(str(NIFTI))
    out, _ = run_hpcm(tmp_path, NIFTI, "--downsample", f, pull=2.0)
    pimg, v = load(out / "displacement_pullback_final.nii.gz")
    assert pimg.shape == img.shape + (1, 3) and np.allclose(pimg.affine, img.affine, atol=1e-3)
    assert int(pimg.header["intent_code"]) == 1007
    assert np.abs(v).max() > 1.0, "the pull-back field is zero: the checks would be void"
    residual, covered = pullback_residual_mm(out, f, img.affine, img.shape)
    assert covered > 0.8  # voxels beyond the lattice's outer nodes have no forward field to check against
    assert residual.max() < 0.02, f"pull-back field misses the forward field's inverse by {residual.max():.3g} mm"
    # Naming and header: the NRRD says which direction it is for Slicer.
    header = (out / "displacement_pullback_final.nrrd").read_bytes().split(b"\n\n")[0].decode("latin-1")
    assert "displacement field type:=resampling" in header, header
    forward = (out / "displacement_final.nrrd").read_bytes().split(b"\n\n")[0].decode("latin-1")
    assert "displacement field type:=modeling" in forward


def test_recipe_is_the_documented_one():
    for doc in ("slicer.md", "io.md"):
        recipe = "\n".join(PLASTIMATCH_RECIPE)
        assert recipe in (DOCS / doc).read_text(), f"docs/{doc} does not show the tested recipe:\n{recipe}"


@needs_plastimatch
@pytest.mark.parametrize("f", [1, 2])  # f = 1 takes about 5 s here
def test_plastimatch_recipe_reproduces_the_deformed_ct(f, tmp_path):
    img = nib.load(str(NIFTI))
    array = np.asarray(img.dataobj).astype(np.float64)
    out, _ = run_hpcm(tmp_path, NIFTI, "--downsample", f, pull=2.0)
    # The recipe as written, in the export folder with the CT beside it as ct.nii.gz.
    (out / "ct.nii.gz").symlink_to(NIFTI.resolve())
    for line in PLASTIMATCH_RECIPE:
        r = subprocess.run(shlex.split(line), cwd=out, capture_output=True, text=True)
        assert r.returncode == 0, line + "\n" + r.stdout + r.stderr
    warped = load(out / "warped.nii.gz")[1].astype(np.float64)
    deformed = load(out / "deformed_final.nii.gz")[1].astype(np.float64)
    change = np.sqrt(np.mean((deformed - array) ** 2))
    assert change > 1.0, "the deformation changed nothing: the check would be void"
    err = np.sqrt(np.mean((warped - deformed) ** 2)) / change
    print(f"f = {f}: rms change {change:.2f} HU; plastimatch recipe vs hpcm {err:.3%} of it")
    assert err < RECIPE_TOLERANCE, f"f = {f}: the recipe differs from hpcm's deformed CT by {err:.2%}"


def test_64_bit_labels_keep_their_values(abdomen, tmp_path):
    img, hu = abdomen[1], abdomen[2]
    big = np.zeros(hu.shape, dtype=np.uint64)
    big[hu >= -500] = 2**63 + 12345  # beyond int64 and double precision: copied, never converted
    big[hu >= 375] = 2**40 + 1
    path = tmp_path / "big.nii.gz"
    nib.save(nib.Nifti1Image(big, img.affine, dtype=np.uint64), str(path))
    out, _ = run_hpcm(tmp_path, NIFTI, "--downsample", 4, "--warp-labels", path, pull=1.0)
    warped = load(out / "warped_big_final.nii.gz")[1]
    assert warped.dtype == np.uint64
    assert set(np.unique(warped)) == set(np.unique(big))
