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
    for path in list(ROOT.glob("experiments/*/config.yaml")) + [ROOT / n / "config.yaml" for n in ("gradcheck", "inverse", "sitl")]:
        assert isinstance(configtools.load_yaml(path), dict), path


def test_a_sweep_listing_a_spacing_twice_is_refused(tmp_path):
    import importlib.util

    folder = copied_experiment("tgv2d", tmp_path / "study", dx=[0.05, 0.05])
    spec = importlib.util.spec_from_file_location("copied_settings", folder / "settings.py")
    settings = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(settings)
    with pytest.raises(sph.ConfigError, match=r"profiles\.smoke\.dx\[1\]: 0\.05 appears twice"):
        settings.load("smoke")
