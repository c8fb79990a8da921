"""The integrity figures of `hpcm run --export` (export.json), checked independently.

Run by CTest (io_export_checks) as
  /usr/bin/python3 -m pytest --noconftest tests/io/test_export_checks.py
with HPCM_CLI (the hpcm binary) and HPCM_SHARED_DATA (../shared/data) in the environment.

nibabel loads the exported displacement field; numpy computes its Jacobian determinant at the
8 corners of every cell (the map p -> p + u(p) in LPS millimetres) without any hpcm code, and
the side-car's figures (cells checked, folded cells, smallest determinant) and grids must agree.
The numpy check itself is shown to find a fold planted in a field. The phantom case always runs;
the DICOM series case (the one that used to fold) skips when ../shared/data is absent.
"""
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

nib = pytest.importorskip("nibabel")

HPCM = os.environ.get("HPCM_CLI", "")
DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
DICOM = DATA / "abdomen-ct-dicom"
if not HPCM or not Path(HPCM).is_file():
    raise RuntimeError("HPCM_CLI must name the hpcm binary")

LPS_FROM_RAS = np.diag([-1.0, -1.0, 1.0])


def corner_determinants(u, affine):
    """det(I + du/dp) at the 8 corners of every cell of a displacement field u (nx, ny, nz, 3) in
    LPS mm on a grid with NIfTI (RAS) affine `affine`. Returns an array (8, nx-1, ny-1, nz-1)."""
    a = LPS_FROM_RAS @ affine[:3, :3]  # index -> LPS mm, column k = one step along index axis k
    u = u.astype(np.float64)
    diffs = [np.diff(u, axis=k) for k in range(3)]  # edge differences along each index axis
    n = [s - 1 for s in u.shape[:3]]
    dets = []
    for corner in range(8):
        c = [(corner >> k) & 1 for k in range(3)]
        edges = []
        for k in range(3):
            # Edge along axis k at this corner: the cell's edge between its two layers along k,
            # taken at the corner's position on the other two axes.
            sl = [slice(c[j], c[j] + n[j]) if j != k else slice(0, n[k]) for j in range(3)]
            edges.append(a[:, k] + diffs[k][tuple(sl)])
        e = np.stack(edges, axis=-1)  # (..., 3 rows, 3 columns = edges)
        dets.append(np.linalg.det(e) / np.linalg.det(a))
    return np.stack(dets)


def check_sidecar_against_numpy(out):
    sidecar = json.loads((out / "export.json").read_text())
    final = sidecar["exports"][-1]
    assert final["tag"] == "final"
    img = nib.load(str(out / "displacement_final.nii.gz"))
    u = np.asarray(img.dataobj)[:, :, :, 0, :]
    # The side-car's grid of the field is nibabel's: shape and affine (LPS -> RAS).
    grid = next(f for f in final["files"] if f["file"] == "displacement_final.nii.gz")
    assert tuple(grid["shape"]) == u.shape[:3]
    direction = np.array(grid["direction"]).reshape(3, 3)
    affine = np.eye(4)
    affine[:3, :3] = np.linalg.inv(LPS_FROM_RAS) @ direction @ np.diag(grid["spacing"])
    affine[:3, 3] = np.linalg.inv(LPS_FROM_RAS) @ np.array(grid["origin"])
    assert np.allclose(affine, img.affine, atol=1e-4), f"side-car grid\n{affine}\nnibabel\n{img.affine}"

    dets = corner_determinants(u, img.affine)
    folded = int(np.count_nonzero(np.any(dets <= 0, axis=0)))
    jac = final["displacement_jacobian"]
    assert jac["cells_checked"] == dets[0].size
    assert jac["folded_cells"] == folded
    assert jac["min_det"] == pytest.approx(float(dets.min()), rel=1e-6, abs=1e-9)
    # The cell named as the smallest holds that value (equal values elsewhere may exist).
    i, j, k = jac["min_det_cell"]
    assert dets[:, i, j, k].min() == pytest.approx(float(dets.min()), rel=1e-6, abs=1e-9)
    return final, dets


def run_export(tmp, *source, frames, scenario=None):
    out = tmp / "export"
    cmd = [HPCM, "run", *source, "--frames", str(frames), "--out", str(tmp / "run"), "--export", str(out), "--strict"]
    if scenario:
        cmd += ["--scenario", str(scenario)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, f"{cmd}: exit {r.returncode}\n{r.stderr}"
    assert "warning" not in r.stderr, r.stderr
    return out


def test_numpy_check_finds_a_planted_fold():
    # Without this the agreement below could come from a check that finds nothing.
    affine = np.diag([-2.0, -2.0, 3.0, 1.0])
    u = np.zeros((6, 5, 4, 3))
    assert np.allclose(corner_determinants(u, affine), 1.0)
    u[3, 2, 1, 0] = -5.0  # one node pushed 5 mm past its -x neighbour (2 mm away): folds
    dets = corner_determinants(u, affine)
    assert np.count_nonzero(np.any(dets <= 0, axis=0)) > 0
    u[3, 2, 1, 0] = 1.0  # a small push stays fold-free
    assert corner_determinants(u, affine).min() > 0


def test_phantom_export_is_fold_free_and_converged(tmp_path):
    # A 3-unit anterior pull of the skin over 10 frames, then 5 frames of hold.
    scenario = tmp_path / "pull.toml"
    scenario.write_text('[scenario]\nname = "pull"\nframes = 15\n\n[[grab]]\ncentre = "auto"\nstart = 0\n'
                        "release = 15\nkeyframes = [[10, 0.0, -3.0, 0.0]]\n")
    out = run_export(tmp_path, "--phantom", "32,32,24", frames=15, scenario=scenario)
    final, dets = check_sidecar_against_numpy(out)
    assert final["frame"] == 14 and final["frames_done"] == 15
    assert dets.min() < 0.99, "the field hardly deformed: the check would be weak"
    assert final["displacement_jacobian"]["fold_free"] and final["displacement_jacobian"]["folded_cells"] == 0
    inv = final["deformed_inverse_mapping"]
    assert inv["unconverged_voxels"] == 0 and inv["max_residual_mm"] <= inv["tolerance_mm"]
    assert inv["voxels"] == 32 * 32 * 24
    deformed = next(f for f in final["files"] if f["file"] == "deformed_final.nii.gz")
    assert tuple(deformed["shape"]) == nib.load(str(out / "deformed_final.nii.gz")).shape
    assert final["clean"] and final["problems"] == []


def test_dicom_series_export_is_fold_free_and_converged(tmp_path):
    # The case that used to leave 45 folded cells and 840 unconverged voxels: the paper
    # protocol's pull (20 frames) and hold (10) on the DICOM series down-sampled by 2.
    if not DICOM.is_dir():
        pytest.skip(f"the shared DICOM series ({DICOM}) is absent")
    out = run_export(tmp_path, "--input", str(DICOM), "--downsample", "2", frames=30)
    final, dets = check_sidecar_against_numpy(out)
    assert dets.min() < 0.99, "the field hardly deformed: the check would be weak"
    assert final["displacement_jacobian"]["folded_cells"] == 0
    inv = final["deformed_inverse_mapping"]
    assert inv["voxels"] == 512 * 512 * 20
    assert inv["unconverged_voxels"] == 0 and inv["max_residual_mm"] <= inv["tolerance_mm"]
    print(f"DICOM f=2, 30 frames: min det {dets.min():.6g}, residual {inv['max_residual_mm']:.3g} mm")


def test_strict_without_export_judges_the_frames(tmp_path):
    # Without --export, --strict judges the frames (fold-free here: exit 0); with --no-link-check
    # it could not, and says so before anything is written.
    r = subprocess.run([HPCM, "run", "--phantom", "16,16,12", "--frames", "2", "--strict", "--out", str(tmp_path / "run")],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "fold" not in r.stderr, r.stderr
    r = subprocess.run([HPCM, "run", "--phantom", "16,16,12", "--frames", "2", "--strict", "--no-link-check", "--out",
                        str(tmp_path / "run2")], capture_output=True, text=True)
    assert r.returncode != 0 and "--no-link-check" in r.stderr, r.stderr
    assert not (tmp_path / "run2").exists()
