"""The example script python/examples/paper_protocol.py runs the paper protocol end to end."""
import json
import os
import subprocess
import sys
from pathlib import Path

SOURCE = Path(os.environ.get("HPCM_SOURCE_DIR", Path(__file__).resolve().parents[2]))


def test_paper_protocol_example_writes_tables_and_plot(tmp_path):
    script = SOURCE / "python" / "examples" / "paper_protocol.py"
    r = subprocess.run([sys.executable, str(script), "--phantom", "24,20,16", "--settle", "10", "--out", str(tmp_path)],
                       capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"})
    assert r.returncode == 0, r.stderr
    assert "Table 2" in r.stdout and "Table 3" in r.stdout
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert set(summary["conditions"]) == {"A", "B", "C"}
    assert summary["dims"] == [24, 20, 16] and summary["release_frame"] == 30
    skin_peak = {k: c["peak"]["skin_fat"] for k, c in summary["conditions"].items()}
    assert all(v > 0 for v in skin_peak.values()), skin_peak
    assert summary["params"]["dynamics"]["mode"] == "viscoelastic"  # the base parameters, as read back
    png = (tmp_path / "speed_curves.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10000
