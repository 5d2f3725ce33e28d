"""`make snapshot` names the commit its files were made at: it refuses a working tree with
uncommitted changes to tracked files, or, with --allow-dirty (DIRTY=1), marks every file of the
snapshot as made from that tree; the README's generated provenance line says which. The git
lookup is replaced here (this checkout's own state is never touched), and one test runs the real
lookup on a temporary repository."""
import json
import subprocess

import pandas as pd
import pytest

from report import build, model, provenance, readme_verdicts, snapshot


@pytest.fixture
def results(tmp_path):
    """A finished smoke report with one target's table (every other target not run)."""
    res = tmp_path / "results" / "smoke"
    (res / "fig10").mkdir(parents=True)
    pd.DataFrame({"T_fluid_max": [1.2], "wall_s": [3.0]}).to_csv(res / "fig10" / "metrics.csv", index=False)
    build.write(model.build(res, "smoke"), res / "report")
    return res


def test_a_dirty_tree_is_refused_naming_the_changed_files(results, tmp_path, monkeypatch):
    monkeypatch.setattr(provenance, "dirty_paths", lambda: ["sph/step.py"])
    out = tmp_path / "docs" / "results" / "smoke"
    with pytest.raises(snapshot.DirtyTree, match=r"uncommitted changes \(sph/step.py\).*DIRTY=1"):
        snapshot.snapshot("smoke", results, out)
    assert not out.exists()  # nothing written
    assert snapshot.main(["--profile", "smoke", "--results", str(results), "--out", str(out)]) == 2


def test_allow_dirty_marks_every_file_and_the_readme_line_says_so(results, tmp_path, monkeypatch):
    monkeypatch.setattr(provenance, "dirty_paths", lambda: ["sph/step.py"])
    out = snapshot.snapshot("smoke", results, tmp_path / "docs" / "results" / "smoke", allow_dirty=True)
    prov = json.loads((out / provenance.FILE).read_text())
    assert prov["dirty_tree"] is True and prov["dirty_paths"] == ["sph/step.py"]
    files = {str(f.relative_to(out)) for f in out.rglob("*") if f.is_file()}
    assert files <= set(prov["dirty_files"]), files - set(prov["dirty_files"])
    assert prov["snapshot_commit"].endswith(provenance.DIRTY)
    line = readme_verdicts.provenance(out)[0]
    assert "uncommitted changes" in line and prov["snapshot_commit"][:7] in line
    # the report shows the marks (the file list condensed to its length)
    assert "dirty_files" in (out / "report" / "report.md").read_text()


def test_a_clean_tree_gives_an_unmarked_snapshot_whose_commit_the_readme_states(results, tmp_path, monkeypatch):
    monkeypatch.setattr(provenance, "dirty_paths", lambda: [])
    monkeypatch.setattr(provenance, "_git", lambda *a: "0123456789abcdef" if a[0] == "rev-parse" else "")
    out = snapshot.snapshot("smoke", results, tmp_path / "docs" / "results" / "smoke")
    prov = json.loads((out / provenance.FILE).read_text())
    assert prov["snapshot_commit"] == "0123456789abcdef" and "dirty_tree" not in prov
    line = readme_verdicts.provenance(out)[0]
    assert "commit `0123456`" in line and prov["snapshot_date"] in line and "uncommitted" not in line


def test_dirty_paths_reads_git_status_of_tracked_files(tmp_path, monkeypatch):
    repo = tmp_path / "repo"
    repo.mkdir()

    def git(*args):
        subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True)

    git("init", "-q")
    (repo / "a.txt").write_text("1\n")
    git("add", "a.txt")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "a")
    monkeypatch.setattr(provenance, "ROOT", repo)
    assert provenance.dirty_paths() == [] and not provenance.commit().endswith(provenance.DIRTY)
    (repo / "untracked.txt").write_text("x\n")  # untracked files are not the commit's and not a change
    assert provenance.dirty_paths() == []
    (repo / "a.txt").write_text("2\n")
    assert provenance.dirty_paths() == ["a.txt"] and provenance.commit().endswith(provenance.DIRTY)


def _readme_line(tmp_path, note: str) -> str:
    """The README's provenance line of a snapshot (commit ccc3333) whose provenance has `note` as its
    "restored from snapshot" line."""
    made = tmp_path / "made"
    made.mkdir()
    (made / provenance.FILE).write_text(json.dumps({"snapshot_commit": "ccc3333", "snapshot_date": "d",
                                                     "restored from snapshot": note}))
    return readme_verdicts.provenance(made)[0]


def test_a_restored_folder_made_again_here_is_no_longer_named_restored(tmp_path):
    """`make restore` records the digest of every file it copies; a folder whose restored files were all
    made again here is no longer called restored, and one that keeps some restored files beside new ones
    (a shared folder, one target of it run again) is named "in part", with the count, here and in the
    README line: a partial re-run does not pass its other, older files off as made here."""
    from report import restore

    snap, res = tmp_path / "snap", tmp_path / "results"
    for name in ("fig9", "fig10"):
        (snap / name).mkdir(parents=True)
        (snap / name / "metrics.csv").write_text("a\n1\n")
    (snap / provenance.FILE).write_text(json.dumps({"snapshot_commit": "abc1234", "snapshot_date": "2026-12-05"}))
    assert restore.restore_one(snap, res) == ["fig10", "fig9"]
    assert provenance.restored(res) == "fig10, fig9: from the snapshot of abc1234 (2026-12-05)"
    (res / "fig10" / "metrics.csv").write_text("a\n2\n")              # fig10 made again here
    assert provenance.restored(res).startswith("fig9: from the snapshot of abc1234")
    (res / "fig9" / "fig9.png").write_bytes(b"new")                   # a new figure beside the restored table
    note = provenance.restored(res)
    assert note == "fig9 [in part: 1 of its 2 files as restored]: from the snapshot of abc1234 (2026-12-05)", note
    assert provenance.parse_restored(note) == {"fig9": {"commit": "abc1234", "date": "2026-12-05",
                                                        "part": "[in part: 1 of its 2 files as restored]"}}
    line = _readme_line(tmp_path, note)
    assert "1 of its target folders were restored from an earlier snapshot" in line, line
    assert "1 of them only in part (their other files made for this snapshot)" in line, line
    (res / "fig9" / "metrics.csv").write_text("a\n3\n")               # its last restored file made again
    assert provenance.restored(res) == ""
    # a restore record without digests (written before they were kept) names every folder it copied
    note = json.loads((res / provenance.RESTORED).read_text())
    note.pop("digests")
    (res / provenance.RESTORED).write_text(json.dumps(note))
    assert provenance.restored(res).startswith("fig10, fig9: ")


def test_a_folder_restored_twice_keeps_the_snapshot_it_was_made_for(tmp_path):
    """Restoring from a snapshot that itself restored some folders from an earlier one names, for those
    folders, the earlier snapshot (where their files were made), and the README line counts both."""
    from report import restore

    snap, res = tmp_path / "snap", tmp_path / "results"
    for name in ("fig9", "fig10"):
        (snap / name).mkdir(parents=True)
        (snap / name / "metrics.csv").write_text("a\n1\n")
    (snap / provenance.FILE).write_text(json.dumps({
        "snapshot_commit": "bbb2222", "snapshot_date": "2026-12-06 22:00 UTC",
        "restored from snapshot": "fig9: from the snapshot of aaa1111 (with uncommitted changes) (2026-12-05 18:21 UTC)"}))
    restore.restore_one(snap, res)
    note = provenance.restored(res)
    assert note == ("fig10: from the snapshot of bbb2222 (2026-12-06 22:00 UTC); "
                    "fig9: from the snapshot of aaa1111 (with uncommitted changes) (2026-12-05 18:21 UTC)"), note
    assert provenance.parse_restored(note)["fig9"] == {"commit": "aaa1111 (with uncommitted changes)",
                                                       "date": "2026-12-05 18:21 UTC"}
    line = _readme_line(tmp_path, note)
    assert "2 of its target folders were restored from earlier snapshots (1 from commit `bbb2222`" in line, line
    assert "1 from commit `aaa1111`, uncommitted changes, 2026-12-05 18:21 UTC" in line, line
