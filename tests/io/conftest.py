"""pytest setup for tests/io/test_exports_tools.py: without the shared CT data the whole run
is skipped with exit status 77, which CTest reports as skipped (SKIP_RETURN_CODE 77)."""
import os
from pathlib import Path

import pytest


def pytest_sessionstart(session):
    data = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
    if not (data / "abdomen-ct" / "abdomen_ct.nii.gz").is_file() or not (data / "abdomen-ct-dicom").is_dir():
        pytest.exit(f"SKIP: the shared CT data ({data}) is absent; independent-tool export checks not run", returncode=77)
