"""The config API in one import: frozen-dataclass configs from mappings (`lab.typed`), strict YAML
(`lab.yamlfile`) and profiles with `inherit` and errors that name file, profile and key
(`lab.profiles`), with the core's `ConfigError` and `require` (`sph.errors`) that settings raise.
"""
from sph.errors import ConfigError, is_finite_number, require, require_finite

from .profiles import HARNESS_KEYS, harness_options, load_profile, profile_mapping
from .typed import NAME, from_mapping, merge, require_agree, require_name, to_mapping
from .yamlfile import load_yaml, yaml_error

__all__ = ["ConfigError", "is_finite_number", "require", "require_finite", "HARNESS_KEYS", "harness_options",
           "load_profile", "profile_mapping", "NAME", "from_mapping", "merge", "require_agree", "require_name",
           "to_mapping", "load_yaml", "yaml_error"]
