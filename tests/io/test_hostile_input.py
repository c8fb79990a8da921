"""Hostile input (issue 29) checked against independent tools: nibabel reads the NIfTI files,
pydicom edits the DICOM tags (tests/io/make_bad_dicom.py), the hpcm command line reads them.

Run by CTest (io_hostile_input_tools) as
  /usr/bin/python3 -m pytest --noconftest tests/io/test_hostile_input.py
with HPCM_CLI (the hpcm binary) and HPCM_SHARED_DATA (../shared/data) in the environment. The
NIfTI cases always run; the DICOM cases skip without ../shared/data or pydicom.
"""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

nib = pytest.importorskip("nibabel")

HPCM = os.environ.get("HPCM_CLI", "")
DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
DICOM = DATA / "abdomen-ct-dicom"
HERE = Path(__file__).resolve().parent
if not HPCM or not Path(HPCM).is_file():
    raise RuntimeError("HPCM_CLI must name the hpcm binary")

LPS_FROM_RAS = np.diag([-1.0, -1.0, 1.0])


def hpcm(*args):
    return subprocess.run([HPCM, *map(str, args)], capture_output=True, text=True)


def info_values(stdout):
    """hpcm info's geometry (LPS) as a 4x4 index -> RAS affine, and its HU line."""
    lines = {l[:11].strip(): l[11:] for l in stdout.splitlines() if len(l) > 11 and not l.startswith(" ")}
    sp = [float(x) for x in re.findall(r"[-\d.e+]+", lines["spacing"].split("mm")[0])]
    org = [float(x) for x in lines["origin"].split("mm")[0].split(",")]
    d = np.array([float(x) for x in re.findall(r"[-\d.e+]+", lines["direction"].split("]")[0])]).reshape(3, 3)
    affine = np.eye(4)
    affine[:3, :3] = LPS_FROM_RAS @ d @ np.diag(sp)
    affine[:3, 3] = LPS_FROM_RAS @ np.array(org)
    hu = [float(x) for x in re.findall(r"(?:min|max|mean) ([-\d.e+]+)", lines["HU"])]
    return affine, hu, lines


def ct_like(shape=(16, 14, 12)):
    """int16 stored values 0..~1100 (HU + 1024): air around a water block."""
    v = np.zeros(shape, dtype=np.int16)
    v[3:-3, 3:-3, 2:-2] = 1064
    v[5:8, 5:8, 4:6] = 2024
    return v


# ---- NIfTI: scaled integers (item 7) ----------------------------------------------------------

def test_int16_with_intercept_is_read_as_nibabel_scales_it(tmp_path):
    for slope, inter in [(1.0, -1024.0), (0.5, -1000.0)]:
        img = nib.Nifti1Image(ct_like(), np.diag([2.0, 2.0, 3.0, 1.0]))
        img.header.set_data_dtype(np.int16)
        img.header.set_slope_inter(slope, inter)
        f = tmp_path / "ct.nii.gz"
        nib.save(img, str(f))
        ref = nib.load(str(f)).get_fdata()
        assert ref.min() < -900  # nibabel applies the scaling: the check below is not trivial
        r = hpcm("info", f)
        assert r.returncode == 0, r.stderr
        _, hu, _ = info_values(r.stdout)
        assert hu == pytest.approx([ref.min(), ref.max(), ref.mean()], rel=1e-5, abs=1e-3), (slope, inter, r.stdout)


def test_tiny_slope_is_refused_with_its_value(tmp_path):
    img = nib.Nifti1Image(ct_like().astype(np.float32) - 1024, np.diag([2.0, 2.0, 3.0, 1.0]))
    f = tmp_path / "tiny.nii"
    nib.save(img, str(f))
    raw = bytearray(f.read_bytes())
    raw[112:116] = np.float32(1e-30).tobytes()  # scl_slope
    f.write_bytes(bytes(raw))
    assert nib.load(str(f)).get_fdata().max() < 1e-20  # nibabel applies it: every voxel ~0 HU
    r = hpcm("info", f)
    assert r.returncode != 0, r.stdout
    first = r.stderr.splitlines()[0]
    assert str(f) in first and "scl_slope = 1e-30" in first, first


# ---- NIfTI: qform vs sform (item 9) -----------------------------------------------------------

def oblique_affines():
    c, s = np.cos(0.3), np.sin(0.3)
    sform = np.array([[0, 3.0, 0, 10], [-2.0 * c, 0, -2.5 * s, 20], [2.0 * s, 0, -2.5 * c, 30], [0, 0, 0, 1]])
    qform = np.diag([2.0, 3.0, 2.5, 1.0])
    qform[:3, 3] = [-40, 7, 3]
    return sform, qform


@pytest.mark.parametrize("codes", [(2, 1), (0, 1), (1, 0), (0, 0)])
def test_geometry_follows_nibabel_affine(tmp_path, codes):
    sform_code, qform_code = codes
    sform, qform = oblique_affines()
    img = nib.Nifti1Image(ct_like(), None)
    img.header.set_slope_inter(1.0, -1024.0)
    img.set_sform(sform, code=sform_code)
    img.set_qform(qform, code=qform_code)
    f = tmp_path / "both.nii.gz"
    nib.save(img, str(f))
    expected = nib.load(str(f)).affine
    r = hpcm("info", f)
    assert r.returncode == 0, r.stderr
    affine, _, lines = info_values(r.stdout)
    assert np.allclose(affine, expected, atol=1e-4), f"hpcm\n{affine}\nnibabel\n{expected}"
    used = "sform" if sform_code > 0 else "qform" if qform_code > 0 else "pixdim"
    assert lines["affine"].startswith(used), r.stdout
    if sform_code > 0 and qform_code > 0:
        assert "sform" in r.stderr and "qform" in r.stderr, r.stderr  # the note that they differ


def test_exports_keep_the_input_affine(tmp_path):
    ph = tmp_path / "ph.nii.gz"
    r = hpcm("phantom", "--size", "24,20,16", "--out", ph)
    assert r.returncode == 0, r.stderr
    base = nib.load(str(ph))
    sform, qform = oblique_affines()
    img = nib.Nifti1Image(np.asarray(base.dataobj), None, base.header)
    img.set_sform(sform, code=2)
    img.set_qform(qform, code=1)
    f = tmp_path / "in.nii.gz"
    nib.save(img, str(f))
    r = hpcm("run", "--input", f, "--frames", "1", "--out", tmp_path / "run", "--export", tmp_path / "export")
    assert r.returncode == 0, r.stderr
    expected = nib.load(str(f)).affine
    for name in ["deformed_final.nii.gz", "displacement_final.nii.gz", "labels.nii.gz"]:
        got = nib.load(str(tmp_path / "export" / name)).affine
        assert np.allclose(got, expected, atol=1e-3), f"{name}\n{got}\nnibabel input\n{expected}"
    sidecar = json.loads((tmp_path / "export" / "export.json").read_text())
    assert sidecar["input_geometry"].startswith("sform"), sidecar.get("input_geometry")


# ---- DICOM (items 4 and 12) -------------------------------------------------------------------

def bad_dicom(tmp_path, case):
    pytest.importorskip("pydicom")
    if not DICOM.is_dir():
        pytest.skip(f"the shared DICOM series ({DICOM}) is absent")
    dest = tmp_path / case
    r = subprocess.run([sys.executable, str(HERE / "make_bad_dicom.py"), case, str(DICOM), str(dest)],
                       capture_output=True, text=True, check=True)
    return dest, r.stdout.strip()


@pytest.mark.parametrize("case,tag", [("no_intercept", "RescaleIntercept (0028,1052)"),
                                      ("no_slope", "RescaleSlope (0028,1053)")])
def test_slice_without_rescale_tag_is_named(tmp_path, case, tag):
    dest, what = bad_dicom(tmp_path, case)
    slice_file = what.split(":")[0]
    r = hpcm("info", dest)
    assert r.returncode != 0, f"{what}: read with exit 0\n{r.stdout}"
    first = r.stderr.splitlines()[0]
    assert slice_file in first and tag in first, first


def test_empty_uid_series_can_be_chosen(tmp_path):
    dest, uid = bad_dicom(tmp_path, "named_beside_empty")
    r = hpcm("info", dest)
    assert r.returncode != 0
    first = r.stderr.splitlines()[0]
    m = re.search(r"#(\d+) <empty SeriesInstanceUID>", first)
    assert m and uid in first, first
    r = hpcm("info", dest, "--series", "#" + m.group(1))
    assert r.returncode == 0, r.stderr
    assert "512x512x20" in r.stdout
    assert re.search(r"<empty SeriesInstanceUID> \[read\]", r.stdout), r.stdout
    r = hpcm("info", dest, "--series", uid)
    assert r.returncode == 0, r.stderr
    assert f"{uid} [read]" in r.stdout, r.stdout
    r = hpcm("info", dest, "--series", "#3")
    assert r.returncode != 0 and "#3" in r.stderr.splitlines()[0], r.stderr
