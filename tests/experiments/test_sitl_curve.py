"""sitl/curve.py: a training killed while appending to its learning curve leaves a half-written last
line; reading skips it and a resume's truncation drops it with the lines past the checkpoint, so
the curve of a resumed training reads back whole (no JSON error, no point lost before the
checkpoint)."""
import json

from sitl import curve


def _write(path, rows, tail=""):
    path.write_text("".join(json.dumps(r) + "\n" for r in rows) + tail)


def test_a_half_written_line_is_skipped_and_a_resume_truncates_past_its_step(tmp_path):
    path = tmp_path / "curve.jsonl"
    rows = [{"step": 0, "loss": 0.065}, {"step": 100, "loss": 0.012},
            {"step": 200, "val_mse5": 1e-8, "val_mse20": 2e-7}, {"step": 300, "loss": 0.004}]
    _write(path, rows, tail='{"step": 400, "lo')  # killed mid-append
    c = curve.read(path)
    assert c["loss"] == [(0, 0.065), (100, 0.012), (300, 0.004)]
    assert c["val"] == [(200, 1e-8, 2e-7)]
    curve.truncate(path, 200)  # resumed from the checkpoint at step 200
    assert [json.loads(line) for line in path.read_text().splitlines()] == rows[:3]
    assert not list(tmp_path.glob("*.tmp"))  # replaced atomically, no temporary left behind


def test_a_missing_curve_reads_empty_and_truncates_to_nothing(tmp_path):
    path = tmp_path / "curve.jsonl"
    assert curve.read(path) == {"loss": [], "val": []}
    curve.truncate(path, 100)
    assert not path.exists()
