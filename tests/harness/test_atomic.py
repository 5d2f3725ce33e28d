"""lab/atomic.py: two processes writing the same file at once (make -j2, or two processes of
one sweep rewriting a study's records, which is how the paper atlas crashed with a fixed `.tmp` name:
one process renamed the other's temporary file away) never fail and leave the file whole."""
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WRITER = """
import json, sys
from lab import io
path, tag = sys.argv[1], sys.argv[2]
for i in range(400):
    io.write_metadata(path, {"tag": tag, "i": i, "pad": "x" * 4000})
"""


def test_two_processes_rewriting_one_record_never_fail_and_leave_it_whole(tmp_path):
    path = tmp_path / "run" / "record.json"
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(path), tag], cwd=ROOT, stderr=subprocess.PIPE,
                              text=True) for tag in ("a", "b")]
    errs = [p.communicate(timeout=300)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    rec = json.loads(path.read_text())
    assert rec["tag"] in ("a", "b") and rec["i"] == 399 and len(rec["pad"]) == 4000
    assert sorted(p.name for p in path.parent.iterdir()) == ["record.json"]  # no temporary file left
