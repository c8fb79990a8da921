"""Exports checked with tools nobody here wrote: nibabel, pydicom and plastimatch.

Run by CTest (io_exports_independent_tools) as
  /usr/bin/python3 -m pytest tests/io/test_exports_tools.py
with HPCM_CLI (the hpcm binary) and HPCM_SHARED_DATA (../shared/data) in the environment.
Exits 77 (CTest: skipped) when the shared CT data is absent (conftest.py).

What is checked, for the abdomen NIfTI (RAS-stored), a flipped + permuted copy of it, a tilted
(oblique) copy, a cropped + down-sampled run on the permuted copy, and the DICOM series:
  * nibabel reads input and exports with the same array shape and the same affine (labels and
    field on the input's grid coarsened by the down-sampling factor);
  * the exports hold the input's voxels in the input's index order (labels = the tissue
    classes numpy computes from the input's own array; far from the tool the deformed CT is the
    input's array, voxel for voxel);
  * plastimatch inverts the exported forward field (xf-invert) and warps the input with it;
    the result matches hpcm's deformed CT (tolerance below) and warping with the un-inverted
    field does not (so the check can fail).
"""
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

nib = pytest.importorskip("nibabel")

HPCM = os.environ.get("HPCM_CLI", "")
DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
NIFTI = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
DICOM = DATA / "abdomen-ct-dicom"

# (conftest.py skips the whole run, exit status 77, when the shared data is absent.)
if not HPCM or not Path(HPCM).is_file():
    raise RuntimeError("HPCM_CLI must name the hpcm binary")

PLASTIMATCH = shutil.which("plastimatch")
needs_plastimatch = pytest.mark.skipif(PLASTIMATCH is None, reason="plastimatch is not installed (scripts/install-deps.sh)")

# Default tissue thresholds (the paper's): air < -1000 <= skin_fat < 25 <= muscle_organ < 375 <= bone.
THRESHOLDS = (-1000.0, 25.0, 375.0)
LPS_TO_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])

# Tolerance of the plastimatch comparison: rms(plastimatch warp - hpcm deformed CT) must stay
# below 20 % of rms(hpcm deformed CT - input), the change the deformation made. Both resample
# the same input trilinearly; they differ in how the forward field is inverted. hpcm solves
# X = x - u(X) per voxel to 1e-5 lattice units; plastimatch's xf-invert is an iterative
# inversion on the output grid that smooths: next to the grab, where the field is steepest,
# its inverse is off by up to ~0.5 mm (checked with scipy: |X + u(X) - x|), and half a voxel
# at a skin/air edge is hundreds of HU. With 50 iterations (default 20) the measured
# difference is 4-6 % (DICOM at 0.98 mm voxels the largest); warping with the field's wrong
# direction gives > 100 %. The response is local (SPEC §8.8): a small pull changes only the voxels
# next to the grab, where the field is steepest, so the whole change lies where xf-invert smooths
# most: the 1-unit pull of roi_f2 measured 15 % (200 iterations: 15 %; a 2-unit pull: 13 %). The
# inverse mapping's own accuracy is checked against numpy in test_export_checks.py.
PLASTIMATCH_INVERSION_ITERATIONS = 50
WARP_TOLERANCE = 0.20


def classes(hu):
    t1, t2, t3 = THRESHOLDS
    return np.select([hu < t1, hu < t2, hu < t3], [0, 1, 2], 3).astype(np.uint8)


def block_mean(a, f):
    """Mean of complete f x f x f blocks in the array's own index order (what --downsample does)."""
    n = [s // f for s in a.shape]
    a = a[: n[0] * f, : n[1] * f, : n[2] * f].astype(np.float64)
    return a.reshape(n[0], f, n[1], f, n[2], f).mean(axis=(1, 3, 5))


def coarse_affine(affine, f):
    """Affine of the grid coarsened by f: spacing f, first voxel at the centre of the first block."""
    c = np.eye(4)
    c[:3, :3] *= f
    c[:3, 3] = (f - 1) / 2.0
    return affine @ c


def scenario(path, pull, frames):
    """Grab the paper's point (anterior skin) and pull it anterior by `pull` lattice units."""
    path.write_text(
        f'[scenario]\nname = "pull"\nframes = {frames}\n\n[[grab]]\ncentre = "auto"\nstart = 0\n'
        f"release = {frames}\nkeyframes = [[{frames}, 0.0, {-pull}, 0.0]]\n"
    )
    return path


def run_hpcm(tmp, volume, *options, pull=3.0, frames=10):
    out = tmp / "export"
    cmd = [HPCM, "run", "--input", str(volume), "--scenario", str(scenario(tmp / "pull.toml", pull, frames)),
           "--out", str(tmp / "run"), "--export", str(out), *options]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, f"{cmd}: {r.stderr}"
    assert "max link violation" in r.stdout
    return out


def load(path):
    img = nib.load(str(path))
    return img, np.asarray(img.dataobj)


def assert_same_grid(img, affine, shape, what):
    assert img.shape[:3] == tuple(shape), f"{what}: shape {img.shape[:3]}, input {tuple(shape)}"
    assert np.allclose(img.affine, affine, atol=1e-3), f"{what}: affine\n{img.affine}\ninput\n{affine}"


def check_exports_on_input_grid(out, affine, array, f, ext=".nii.gz"):
    """Shapes, affines and index order of the three exports against the input (nibabel/numpy)."""
    shape = array.shape
    coarse = block_mean(array, f) if f > 1 else array
    aff_c = coarse_affine(affine, f)
    labels, lab = load(out / "labels.nii.gz")
    assert_same_grid(labels, aff_c, coarse.shape, "labels")
    assert lab.dtype == np.uint8
    body = lab != 4  # 4: outside the body (SPEC §3; its extent is checked in test_body.py)
    assert body.any()
    np.testing.assert_array_equal(lab[body], classes(coarse)[body], err_msg="labels are not the classes of the input's voxels")
    field, u = load(out / "displacement_final.nii.gz")
    assert_same_grid(field, aff_c, coarse.shape, "displacement field")
    assert field.shape[3:] == (1, 3) and int(field.header["intent_code"]) == 1007
    deformed_path = out / ("deformed_final" + ext)
    if ext == ".nrrd":  # nibabel does not read NRRD: plastimatch converts the format only
        subprocess.run([PLASTIMATCH, "convert", "--input", str(deformed_path), "--output-img",
                        str(out / "deformed_final_converted.nii.gz")], check=True, capture_output=True)
        deformed_path = out / "deformed_final_converted.nii.gz"
    deformed, d = load(deformed_path)
    assert_same_grid(deformed, affine, shape, "deformed CT")
    u = u[:, :, :, 0, :]
    # Where the exported field is zero on every lattice node around a voxel, nothing moved: the
    # deformed CT must hold the input's own voxel there, exactly. (In another index order the
    # still voxels and the input would not line up.)
    still = still_voxels(np.any(u != 0, axis=-1), shape, f)
    assert still.mean() > 0.05, f"only {still.mean():.1%} of the volume is still: the check would be weak"
    mismatch = np.count_nonzero(d[still] != array[still])
    assert mismatch == 0, f"{mismatch} of {still.sum()} still voxels differ from the input's"
    return u, d


def still_voxels(moved, shape, f):
    """Input voxels whose surrounding lattice nodes (trilinear stencil) did not move."""
    idx = []
    for axis in range(3):
        q = (np.arange(shape[axis]) - (f - 1) / 2.0) / f  # continuous lattice index of each voxel
        n = moved.shape[axis]
        lo = np.clip(np.floor(q), 0, n - 1).astype(int)
        hi = np.clip(np.ceil(q), 0, n - 1).astype(int)
        idx.append((lo, hi))
    still = np.ones(shape, dtype=bool)
    for cx in idx[0]:
        for cy in idx[1]:
            for cz in idx[2]:
                still &= ~moved[np.ix_(cx, cy, cz)]
    return still


def check_tool_displacement(u, array, affine, f, pull, spacing):
    """Elements moved exactly by the tool (pull lattice units anterior) are the grabbed ones, and
    they sit at the anterior body surface of the input's own array."""
    tool_lps = np.array([0.0, -pull * spacing, 0.0])  # anterior is -P (LPS components)
    grabbed = np.argwhere(np.all(np.abs(u - tool_lps) < 1e-3, axis=-1))
    assert len(grabbed) > 0, f"no element moved by the tool's {tool_lps} mm"
    # One grabbed element is the paper's grab point: tissue (HU >= -500) with air one lattice
    # step anterior of it.
    coarse = block_mean(array, f) if f > 1 else array
    a = coarse_affine(affine, f)
    step = np.linalg.solve(a[:3, :3], [0.0, spacing, 0.0])  # index step one lattice unit towards A
    surface = [tuple(g) for g in grabbed
               if coarse[tuple(g)] >= -500 > coarse[tuple(int(round(p + s)) for p, s in zip(g, step))]]
    assert surface, f"none of the {len(grabbed)} grabbed elements sits on the anterior body surface of the input"
    assert np.abs(grabbed - np.array(surface[0])).max() <= 2, "grabbed elements are not around one point"


def plastimatch_warp(tmp, input_float, field, fixed, name):
    inverse = tmp / f"{name}_inverse.nii.gz"
    subprocess.run([PLASTIMATCH, "xf-invert", "--input", str(field), "--fixed", str(fixed), "--output", str(inverse),
                    "--iterations", str(PLASTIMATCH_INVERSION_ITERATIONS)], check=True, capture_output=True)
    out = {}
    for tag, xf in (("inverted", inverse), ("wrong_direction", field)):
        path = tmp / f"{name}_{tag}.nii.gz"
        subprocess.run([PLASTIMATCH, "convert", "--input", str(input_float), "--xf", str(xf), "--fixed", str(fixed),
                        "--output-img", str(path), "--interpolation", "linear", "--default-value", "-1000"],
                       check=True, capture_output=True)
        out[tag] = load(path)[1].astype(np.float64)
    return out


def check_plastimatch_agrees(tmp, array, affine, field, deformed, name):
    src = tmp / f"{name}_input_float.nii.gz"
    nib.save(nib.Nifti1Image(array.astype(np.float32), affine), str(src))  # plastimatch warps float images
    fixed = tmp / f"{name}_fixed.nii.gz"
    nib.save(nib.Nifti1Image(deformed.astype(np.float32), affine), str(fixed))
    warped = plastimatch_warp(tmp, src, field, fixed, name)
    change = np.sqrt(np.mean((deformed - array) ** 2))
    assert change > 1.0, "the deformation changed nothing: the check would be void"
    err = np.sqrt(np.mean((warped["inverted"] - deformed) ** 2)) / change
    wrong = np.sqrt(np.mean((warped["wrong_direction"] - deformed) ** 2)) / change
    print(f"{name}: rms change {change:.2f} HU; plastimatch vs hpcm {err:.2%} of it; wrong direction {wrong:.2%}")
    assert err < WARP_TOLERANCE, f"{name}: plastimatch's warp differs from hpcm's deformed CT by {err:.1%}"
    assert wrong > 0.5, f"{name}: the un-inverted field also matches ({wrong:.1%}): the check cannot tell"


# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def original(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("nifti")
    img = nib.load(str(NIFTI))
    out = run_hpcm(tmp, NIFTI)
    return tmp, img, np.asarray(img.dataobj).astype(np.float64), out


def test_nifti_exports_are_on_the_input_grid(original):
    tmp, img, array, out = original
    assert nib.aff2axcodes(img.affine) != ("L", "P", "S"), "expected a file not stored in LPS index order"
    u, _ = check_exports_on_input_grid(out, img.affine, array, 1)
    check_tool_displacement(u, array, img.affine, 1, 3.0, 3.0)


@needs_plastimatch
def test_nifti_plastimatch_warp_matches_the_deformed_ct(original):
    tmp, img, array, out = original
    d = load(out / "deformed_final.nii.gz")[1].astype(np.float64)
    check_plastimatch_agrees(tmp, array, img.affine, out / "displacement_final.nii.gz", d, "nifti")


def test_flipped_permuted_copy_gives_the_same_results_in_its_own_order(original, tmp_path):
    _, img, array, out = original
    # Stored order (P, S, L)-ish: axes permuted and two of them flipped, affine adjusted by nibabel.
    transform = np.array([[1, -1], [2, 1], [0, -1]])
    copy = img.as_reoriented(transform)
    path = tmp_path / "permuted.nii.gz"
    nib.save(copy, str(path))
    copy_array = np.asarray(copy.dataobj).astype(np.float64)
    assert copy_array.shape != array.shape
    out_p = run_hpcm(tmp_path, path)
    check_exports_on_input_grid(out_p, copy.affine, copy_array, 1)
    # The copy holds the same voxels at the same places: the lattice and the simulation are the
    # same, so each export, brought back to the original's order by nibabel, equals the original's.
    inverse = nib.orientations.ornt_transform(nib.io_orientation(copy.affine), nib.io_orientation(img.affine))
    for name in ("labels.nii.gz", "deformed_final.nii.gz", "displacement_final.nii.gz"):
        mine = nib.load(str(out_p / name))
        restored = np.asarray(nib.orientations.apply_orientation(np.asarray(mine.dataobj), inverse))
        reference = np.asarray(nib.load(str(out / name)).dataobj)
        np.testing.assert_allclose(restored, reference, atol=1e-4, err_msg=name)


def test_oblique_copy_keeps_its_affine(original, tmp_path):
    _, img, array, out = original
    angle = np.radians(12.0)
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])  # about the scanner z axis (RAS)
    tilted = nib.Nifti1Image(np.asarray(img.dataobj), rot @ img.affine)
    path = tmp_path / "oblique.nii.gz"
    nib.save(tilted, str(path))
    out_o = run_hpcm(tmp_path, path)
    u, d = check_exports_on_input_grid(out_o, tilted.affine, array, 1)
    # Same voxels, rotated in space: same lattice, same simulation; the field's millimetre
    # vectors turn with the volume (LPS components).
    rot_lps = LPS_TO_RAS[:3, :3] @ rot[:3, :3] @ LPS_TO_RAS[:3, :3]
    u_ref = np.asarray(nib.load(str(out / "displacement_final.nii.gz")).dataobj)[:, :, :, 0, :]
    np.testing.assert_allclose(u, u_ref @ rot_lps.T, atol=1e-3)
    np.testing.assert_allclose(d, np.asarray(nib.load(str(out / "deformed_final.nii.gz")).dataobj), atol=1e-2)
    if PLASTIMATCH:
        check_plastimatch_agrees(tmp_path, array, tilted.affine, out_o / "displacement_final.nii.gz",
                                 d.astype(np.float64), "oblique")


def test_roi_and_downsample_take_the_files_own_indices(tmp_path):
    img = nib.load(str(NIFTI)).as_reoriented(np.array([[2, 1], [0, -1], [1, -1]]))
    path = tmp_path / "permuted.nii.gz"
    nib.save(img, str(path))
    array = np.asarray(img.dataobj).astype(np.float64)
    lo, hi = (10, 4, 6), (100, 95, 117)  # in this file's own (permuted) voxel indices
    out = run_hpcm(tmp_path, path, "--roi", ",".join(map(str, lo + hi)), "--downsample", "2", pull=1.0)
    sub = array[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    shifted = img.affine.copy()
    shifted[:3, 3] = img.affine[:3, :3] @ lo + img.affine[:3, 3]
    u, d = check_exports_on_input_grid(out, shifted, sub, 2)
    check_tool_displacement(u, sub, shifted, 2, 1.0, 6.0)
    if PLASTIMATCH:
        check_plastimatch_agrees(tmp_path, sub, shifted, out / "displacement_final.nii.gz", d.astype(np.float64),
                                 "roi_f2")


def dicom_series_by_pydicom():
    """The series as DICOM defines it: columns, rows, slices sorted along the slice normal; HU."""
    pydicom = pytest.importorskip("pydicom")
    slices = [pydicom.dcmread(str(p)) for p in sorted(DICOM.iterdir()) if p.is_file()]
    row, col = (np.array(slices[0].ImageOrientationPatient[i:i + 3], dtype=float) for i in (0, 3))
    normal = np.cross(row, col)
    slices.sort(key=lambda s: float(np.dot(normal, np.array(s.ImagePositionPatient, dtype=float))))
    first, last = (np.array(s.ImagePositionPatient, dtype=float) for s in (slices[0], slices[-1]))
    dz = (last - first) / (len(slices) - 1)
    dr, dc = (float(v) for v in slices[0].PixelSpacing)  # between rows, between columns
    lps = np.eye(4)
    lps[:3, 0], lps[:3, 1], lps[:3, 2], lps[:3, 3] = row * dc, col * dr, dz, first
    hu = np.stack([s.pixel_array.T * float(s.RescaleSlope) + float(s.RescaleIntercept) for s in slices], axis=-1)
    return hu.astype(np.float64), LPS_TO_RAS @ lps


@needs_plastimatch
def test_dicom_series_exports_on_its_grid(tmp_path):
    array, affine = dicom_series_by_pydicom()
    assert array.shape == (512, 512, 20)
    # Down-sampled by 2 (labels and field 256x256x10); the deformed CT is on the full grid.
    out = run_hpcm(tmp_path, DICOM, "--downsample", "2", pull=1.5, frames=5)
    u, d = check_exports_on_input_grid(out, affine, array, 2, ext=".nrrd")
    spacing = 2 * float(np.linalg.norm(affine[:3, 1]))
    check_tool_displacement(u, array, affine, 2, 1.5, spacing)
    check_plastimatch_agrees(tmp_path, array, affine, out / "displacement_final.nii.gz", d.astype(np.float64), "dicom")
