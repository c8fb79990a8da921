"""A write that does not fit (a full disk, here a file size limit) raises and leaves no file."""
import os
import subprocess
import sys

import pytest

SCRIPT = r"""
import os, resource, signal, sys
import hpcm
path, limit = sys.argv[1], int(sys.argv[2])
v = hpcm.phantom((64, 64, 48))
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # write() then fails with EFBIG, as on a full disk
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
try:
    hpcm.write_volume(v, path)
except hpcm.Error as e:
    print("ERROR", e)
    sys.exit(3)
print("WROTE")
"""


@pytest.mark.parametrize("ext", ["nii.gz", "nii", "nrrd", "mha"])
def test_write_volume_that_does_not_fit_raises(tmp_path, ext):
    import hpcm

    full = tmp_path / f"whole.{ext}"
    hpcm.write_volume(hpcm.phantom((64, 64, 48)), str(full))
    size = full.stat().st_size
    target = tmp_path / f"cut.{ext}"
    p = subprocess.run([sys.executable, "-c", SCRIPT, str(target), str(size // 2)], capture_output=True, text=True,
                       timeout=120, env=os.environ)
    assert p.returncode == 3, (p.returncode, p.stdout, p.stderr)
    assert "write failed" in p.stdout or "cannot write" in p.stdout, p.stdout
    assert not target.exists()
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".hpcm-tmp")]
