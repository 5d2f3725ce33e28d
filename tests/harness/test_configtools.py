"""Configs say what they mean (lab.configtools): a key written twice in one YAML mapping is refused
naming both lines (YAML would keep the last silently), and a sweep that lists a value twice is
refused naming the entry (it listed every run twice in fig5/metrics.csv)."""
import pytest

import sph
from lab import configtools
from sph_test_helpers import ROOT, copied_experiment


def test_a_key_written_twice_is_refused_naming_both_lines(tmp_path):
    cfg = tmp_path / "config.yaml"
    cfg.write_text("profiles:\n  smoke:\n    t_end: 4.0\n    frames: 10\n    t_end: 2.0\n")
    with pytest.raises(sph.ConfigError, match=r"config\.yaml:5: key 't_end' is written twice in one mapping \(lines 3 and 5\)"):
        configtools.load_yaml(cfg)
    cfg.write_text("profiles:\n  smoke:\n    t_end: 4.0\n    frames: 10\n")
    assert configtools.load_yaml(cfg)["profiles"]["smoke"]["t_end"] == 4.0


def test_every_committed_config_has_unique_keys():
    for path in list(ROOT.glob("experiments/*/config.yaml")) + [ROOT / n / "config.yaml" for n in ("gradcheck", "inverse")]:
        assert isinstance(configtools.load_yaml(path), dict), path


def test_a_sweep_listing_a_spacing_twice_is_refused(tmp_path):
    from lab.experiment import load_settings

    folder = copied_experiment("tgv2d", tmp_path / "study", dx=[0.05, 0.05])
    with pytest.raises(sph.ConfigError, match=r"profiles\.smoke\.dx\[1\]: 0\.05 appears twice"):
        load_settings(folder, "smoke")


def _load(folder):
    """The folder's settings loader `load(profile)`: the protocol's (lab.experiment) for a folder with a
    study.py, else its settings.py's."""
    import functools
    import importlib.util

    if (folder / "study.py").exists():
        from lab.experiment import load_settings

        return functools.partial(load_settings, folder)
    spec = importlib.util.spec_from_file_location(f"settings_{folder.name}", folder / "settings.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.load


@pytest.mark.parametrize("name, edit, blamed", [
    ("dambreak2d", {"dx": 0.3}, r"profiles\.smoke\.dx: .*not a whole number of particle spacings"),
    ("tgv3d", {"t_end": 0.6}, r"profiles\.smoke\.t_end: .*must be below t_end / 2"),
])
def test_a_rule_between_keys_blames_the_key_the_user_changed(tmp_path, name, edit, blamed):
    """A dx change was blamed on `columns[0].height`, a t_end change on `analysis.dissipation_span`
    (keys the user never touched): the key changed since the last commit comes first."""
    import subprocess

    import yaml

    folder = copied_experiment(name, tmp_path / "experiments" / name)   # its references at ../../validation_refs
    (tmp_path / "validation_refs").symlink_to(ROOT / "validation_refs")
    for cmd in (["init", "-q"], ["add", "-A"], ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "copy"]):
        subprocess.run(["git", *cmd], cwd=tmp_path, check=True, capture_output=True)
    cfg = yaml.safe_load((folder / "config.yaml").read_text())
    cfg["profiles"]["smoke"].update(edit)                      # the user's edit, not committed
    (folder / "config.yaml").write_text(yaml.safe_dump(cfg))
    with pytest.raises(sph.ConfigError, match=blamed + r".*\(changed since the last commit\)"):
        _load(folder)("smoke")


def test_a_fixed_length_tuple_key_is_parsed_entry_by_entry():
    """`tuple[float, float]` keys (the stability suite's column / tank) were parsed with types and
    values swapped: a config that set one failed with a TypeError far from the config."""
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Box:
        size: tuple[float, float] = (1.0, 1.0)

    assert configtools.from_mapping(Box, {"size": [2, 0.5]}).size == (2.0, 0.5)
    with pytest.raises(sph.ConfigError, match=r"size\[1\]: expected a number"):
        configtools.from_mapping(Box, {"size": [2.0, "x"]})
    with pytest.raises(sph.ConfigError, match=r"size: expected 2 entries, got 3"):
        configtools.from_mapping(Box, {"size": [1.0, 2.0, 3.0]})


def test_devices_is_a_harness_key_of_every_profile(tmp_path):
    """`devices:` (issue 40) is read by the harness, never by a study's Settings: a profile may set it
    (default 1), the command line's --devices overrides it, and a bad value is refused naming the key."""
    from lab.experiment import Experiment

    folder = copied_experiment("tgv2d", tmp_path / "study", devices=2)
    assert Experiment(folder, "smoke", tmp_path / "r").devices == 2
    assert Experiment(folder, "smoke", tmp_path / "r", devices=3).devices == 3
    assert Experiment(ROOT / "experiments" / "tgv2d", "smoke", tmp_path / "r").devices == 1
    spec = Experiment(folder, "smoke", tmp_path / "r").spec(Experiment(folder, "smoke", tmp_path / "r").runs[0])
    assert spec.devices == 2
    bad = copied_experiment("tgv2d", tmp_path / "bad", devices=0)
    with pytest.raises(sph.ConfigError, match=r"profiles\.smoke\.devices: must be a whole number >= 1, got 0"):
        Experiment(bad, "smoke", tmp_path / "r")
