"""The body (SPEC §3) that `hpcm info` reports, against an independent scipy computation.

Run by CTest (io_body_checks) as
  /usr/bin/python3 -m pytest --noconftest tests/io/test_body.py
with HPCM_CLI (the hpcm binary) and HPCM_SHARED_DATA (../shared/data) in the environment.

The reference reads the CT with nibabel (the DICOM series with pydicom), block-averages it by
the same factor and finds the body with scipy.ndimage: HU >= -500, an opening with a ball of
radius 2 elements (erosion with the image border counted as foreground, as ITK does), the
largest 6-connected component, given back what the opening took within its radius (a dilation
by the same ball, kept to HU >= -500), holes filled. hpcm's count must be within 2 % of it. The
phantom cases always run; the real CTs skip when ../shared/data is absent.
"""
import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

ndimage = pytest.importorskip("scipy.ndimage")

HPCM = os.environ.get("HPCM_CLI", "")
DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
CT = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
DICOM = DATA / "abdomen-ct-dicom"
if not HPCM or not Path(HPCM).is_file():
    raise RuntimeError("HPCM_CLI must name the hpcm binary")

BODY_LINE = re.compile(r"^body: (\d+) elements \(.*\); left out of the statistics: (\d+) outside air .* and (\d+) outside objects",
                       re.M)


def hpcm_body(args):
    """(body, outside air, outside objects) from `hpcm info`."""
    out = subprocess.run([HPCM, "info", *args], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    m = BODY_LINE.search(out.stdout)
    assert m, "hpcm info printed no body line:\n" + out.stdout
    return tuple(int(g) for g in m.groups())


def block_mean(hu, f):
    """Mean of complete f x f x f blocks (what --downsample does), in the array's own axis order."""
    n = [s // f for s in hu.shape]
    hu = hu[: n[0] * f, : n[1] * f, : n[2] * f].astype(np.float64)
    return hu.reshape(n[0], f, n[1], f, n[2], f).mean(axis=(1, 3, 5))


def scipy_body(hu):
    """The body mask of SPEC §3 with scipy.ndimage, independently of hpcm and ITK."""
    r = 2
    g = np.mgrid[-r : r + 1, -r : r + 1, -r : r + 1]
    ball = (g ** 2).sum(axis=0) <= (r + 0.5) ** 2  # a radius-r digital ball (voxel centres within r + 1/2)
    dense = hu >= -500
    opened = ndimage.binary_dilation(ndimage.binary_erosion(dense, ball, border_value=1), ball, border_value=0)
    six = ndimage.generate_binary_structure(3, 1)
    labels, n = ndimage.label(opened, six)
    if n == 0:
        return np.zeros_like(dense)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    largest = labels == sizes.argmax()
    # What the opening shaved off the body's surface within its radius comes back (non-air only).
    regrown = ndimage.binary_dilation(largest, ball) & dense
    return ndimage.binary_fill_holes(regrown, six)


def check_against_reference(args, hu):
    body, air, objects = hpcm_body(args)
    ref = scipy_body(hu)
    ref_body = int(ref.sum())
    ref_objects = int((~ref & (hu >= -500)).sum())
    print(f"{args}: hpcm body {body}, outside air {air}, objects {objects}; scipy body {ref_body}, objects {ref_objects}")
    assert body + air + objects == hu.size
    assert ref_body > 0
    assert abs(body - ref_body) <= 0.02 * ref_body, f"hpcm counts {body} body elements, scipy {ref_body}"
    return body, air, objects


def test_table_phantom_leaves_the_table_out():
    # The phantom as a file would be read: the same lattice the CLI builds (f = 1).
    body, air, objects = hpcm_body(["--phantom", "64,64,48", "--phantom-variant", "table"])
    assert objects > 64 * 48  # the table's shells: at least one full row under the body
    assert air > 0


def test_volume_without_body_says_so(tmp_path):
    nib = pytest.importorskip("nibabel")
    path = tmp_path / "air.nii.gz"
    nib.save(nib.Nifti1Image(np.full((12, 12, 12), -1000, np.int16), np.eye(4)), str(path))
    out = subprocess.run([HPCM, "info", str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "body: none found" in out.stdout and "statistics cover every element" in out.stdout, out.stdout


@pytest.mark.skipif(not CT.is_file(), reason="../shared/data is absent")
def test_abdomen_ct_half_resolution_matches_scipy():
    nib = pytest.importorskip("nibabel")
    img = nib.load(str(CT))
    hu = np.asarray(img.dataobj, dtype=np.float32)
    body, air, objects = check_against_reference([str(CT), "--downsample", "2"], block_mean(hu, 2))
    assert air > 0.2 * body  # the air around the patient, and its noise, is left out


def dicom_stack(folder):
    """HU of a DICOM series, slices sorted along their normal (as hpcm/ITK read it)."""
    pydicom = pytest.importorskip("pydicom")
    slices = [pydicom.dcmread(str(p)) for p in sorted(folder.iterdir()) if p.is_file()]
    o = np.array(slices[0].ImageOrientationPatient, dtype=float)
    normal = np.cross(o[:3], o[3:])
    slices.sort(key=lambda s: float(np.dot(normal, np.array(s.ImagePositionPatient, dtype=float))))
    return np.stack([s.pixel_array.astype(np.float64) * float(getattr(s, "RescaleSlope", 1)) +
                     float(getattr(s, "RescaleIntercept", 0)) for s in slices], axis=-1)


@pytest.mark.skipif(not DICOM.is_dir(), reason="../shared/data is absent")
def test_dicom_series_half_resolution_matches_scipy():
    hu = dicom_stack(DICOM)
    check_against_reference([str(DICOM), "--downsample", "2"], block_mean(hu, 2))


def test_experiment_summary_says_what_was_left_out(tmp_path):
    import json
    phantom = ["--phantom", "24,24,16", "--phantom-variant", "table"]
    body, air, objects = hpcm_body(phantom)
    out = subprocess.run([HPCM, "experiment", *phantom, "--no-report", "--out", str(tmp_path / "x")],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "note: body: %d elements" % body in out.stderr
    s = json.loads((tmp_path / "x" / "summary.json").read_text())
    b = s["body"]
    assert b["search"] == "found"
    assert (b["counted_elements"], b["left_out"]["outside_air"], b["left_out"]["outside_objects"]) == (body, air, objects)
    assert sum(b["counted_class_count"].values()) == body
    assert b["why"].startswith("body: %d elements" % body)
