"""Frozen-dataclass configs from plain mappings (YAML), validated on construction.

`from_mapping(Cls, data, where)` rejects unknown keys and wrong types with a message that names the
full key path (e.g. ``numerics.cfl``), and recurses into nested config dataclasses. Classes add
their own value checks in ``__post_init__`` by raising ``ConfigError`` via ``require``.
"""
import dataclasses
import hashlib
import json
import types
import typing
from pathlib import Path
from typing import Optional

import yaml


class ConfigError(ValueError):
    """A configuration value is unknown, mistyped or inconsistent; the message names the key."""


def require(cond: bool, key: str, msg: str) -> None:
    if not cond:
        raise ConfigError(f"{key}: {msg}")


def _check_type(value, tp, key):
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is typing.Any:
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _check_type(value, a, key)
            except ConfigError as e:
                errors.append(e)
        if len(errors) == 1:
            raise errors[0]
        raise ConfigError(f"{key}: {value!r} does not match {tp}")
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{key}: expected a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_check_type(v, args[0], f"{key}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(f"{key}: expected {len(args)} entries, got {len(value)}")
        return tuple(_check_type(v, a, f"{key}[{i}]") for i, (v, a) in enumerate(zip(args, value)))
    if dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        return from_mapping(tp, value, key)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key}: expected a number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key}: expected an integer, got {value!r}")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key}: expected true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a string, got {value!r}")
        return value
    if isinstance(tp, type) and not isinstance(value, tp):
        raise ConfigError(f"{key}: expected {tp.__name__}, got {value!r}")
    return value


def from_mapping(cls, data, where: str = ""):
    """Build config dataclass `cls` from a mapping, checking keys and types; `where` prefixes keys."""
    prefix = f"{where}." if where else ""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{where or cls.__name__}: expected a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(
            f"{prefix}{unknown[0]}: unknown key (known keys of {where or cls.__name__}: {', '.join(sorted(fields))})"
        )
    kwargs = {}
    for name, value in data.items():
        kwargs[name] = _check_type(value, hints[name], prefix + name)
    missing = [n for n, f in fields.items() if n not in kwargs and f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING]
    if missing:
        raise ConfigError(f"{prefix}{missing[0]}: required key is missing")
    try:
        return cls(**kwargs)
    except ConfigError as e:
        msg = str(e)
        if prefix and not msg.startswith(prefix):
            # classes name their own keys as "<section>.<key>"; drop the section if `where` ends with it
            section = where.split(".")[-1] + "."
            if msg.startswith(section):
                msg = msg[len(section):]
            raise ConfigError(prefix + msg) from None
        raise


def load_yaml(path) -> dict:
    """Read a YAML mapping; an empty file is an empty mapping."""
    path = Path(path)
    with path.open() as f:
        data = yaml.safe_load(f)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    return data


def merge(base: dict, override: dict) -> dict:
    """Recursive dict merge: `override` wins; nested mappings are merged key by key."""
    out = dict(base)
    for k, v in (override or {}).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


def to_mapping(cfg) -> dict:
    """Plain-dict view of a config dataclass (tuples as lists), e.g. for metadata files."""
    def conv(x):
        if dataclasses.is_dataclass(x):
            return {f.name: conv(getattr(x, f.name)) for f in dataclasses.fields(x)}
        if isinstance(x, tuple):
            return [conv(v) for v in x]
        return x
    return conv(cfg)


def profile_mapping(path, profile: str, overrides: Optional[dict] = None) -> dict:
    """The merged mapping of profile `profile` of a YAML file with a single top-level key
    `profiles`: a profile may say `inherit: <other>` to be merged key by key over that profile
    (lists are replaced); `overrides` (a mapping) is merged last."""
    data = load_yaml(path)
    unknown = sorted(set(data) - {"profiles"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown key (known keys: profiles)")
    return merge(_resolve_profile(data.get("profiles") or {}, profile, ()), overrides or {})


def load_profile(cls, path, profile: str, overrides: Optional[dict] = None):
    """Build `cls` from profile `profile` of a YAML file (see `profile_mapping`). Errors name the
    key path, e.g. ``profiles.smoke.dx[0]``."""
    return from_mapping(cls, profile_mapping(path, profile, overrides), f"profiles.{profile}")


def _resolve_profile(profiles: dict, name: str, seen: tuple) -> dict:
    if name not in profiles:
        raise ConfigError(f"profiles.{name}: no such profile (known: {', '.join(sorted(profiles))})")
    if name in seen:
        raise ConfigError(f"profiles.{name}.inherit: circular inheritance {' -> '.join(seen + (name,))}")
    own = dict(profiles[name] or {})
    parent = own.pop("inherit", None)
    if parent is None:
        return own
    if not isinstance(parent, str):
        raise ConfigError(f"profiles.{name}.inherit: expected a profile name, got {parent!r}")
    return merge(_resolve_profile(profiles, parent, seen + (name,)), own)


def digest(obj) -> str:
    """Short stable hash of a JSON-able object (configs via `to_mapping`), for run fingerprints."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def source_hash(root, files) -> str:
    """Short hash of the solver sources (`root`/sph/**/*.py) and the given extra files, so that a
    cached result is reused only while the code that made it is unchanged."""
    root = Path(root)
    h = hashlib.sha256()
    for p in sorted((root / "sph").rglob("*.py")) + [Path(f) for f in files]:
        h.update(str(Path(p).resolve().relative_to(root.resolve())).encode())
        h.update(Path(p).read_bytes())
    return h.hexdigest()[:16]
