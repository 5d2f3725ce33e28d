"""Profiles of an experiment's config.yaml: `profiles: {name: {inherit: other, ...}}` merged key by
key along `inherit`, command-line overrides last, each key's origin kept so that an error names the
file, the profile that wrote the bad key and the key (`locate`); a rule broken between keys names
the one changed since the last commit first (`locate_disagreement`, which asks git for the committed
file). The harness's own keys (`HARNESS_KEYS`, e.g. devices) are read here and never reach a
study's Settings.
"""
import re
from pathlib import Path
from typing import Optional

import yaml

from sph.errors import ConfigError

from .typed import from_mapping, merge
from .yamlfile import load_yaml


def profile_mapping(path, profile: str, overrides: Optional[dict] = None, with_origins: bool = False):
    """The merged mapping of profile `profile` of a YAML file with a single top-level key
    `profiles`: a profile may say `inherit: <other>` to be merged key by key over that profile
    (lists are replaced); `overrides` (a mapping) is merged last.

    With `with_origins`, returns (mapping, origins): origins maps each key path (a tuple, e.g.
    ("numerics", "cfl")) to the profile it was written in, or "command line" for `overrides`
    (see `key_origin`)."""
    data = load_yaml(path)
    unknown = sorted(set(data) - {"profiles"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown key (known keys: profiles)", file=str(path), profile=profile,
                          key=unknown[0])
    try:
        own, origins = _resolve_profile(data.get("profiles") or {}, profile, ())
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}", file=str(path), profile=profile) from None
    out = merge(own, overrides or {})
    origins = _merge_origins(origins, overrides or {}, "command line")
    return (out, origins) if with_origins else out


_KEY_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def key_path(key: str) -> tuple:
    """"numerics.cfl" -> ("numerics", "cfl"); "methods[0].effects" -> ("methods", 0, "effects")."""
    return tuple(int(m.group(2)) if m.group(2) is not None else m.group(1) for m in _KEY_PART.finditer(key))


def key_origin(origins: dict, key, default: Optional[str] = None) -> Optional[str]:
    """The profile that wrote `key` (a path string or tuple): the origin of its longest prefix
    recorded in `origins` (list entries belong to the profile that wrote the list)."""
    parts = key_path(key) if isinstance(key, str) else tuple(key)
    for n in range(len(parts), 0, -1):
        if parts[:n] in origins:
            return origins[parts[:n]]
    return default


def locate(error: ConfigError, path, profile: str, origins: dict) -> ConfigError:
    """`error` (whose message starts with "profiles.<profile>.<key>: ...") re-worded to name the file,
    the profile the key is written in and the key: "<file>: profiles.<origin>.<key>: ... (profile
    <profile> inherits it from <origin>)", or "<file>: <key>: ... (set on the command line over
    profile <profile>)" for an override. Returns a new ConfigError carrying file/profile/origin/key."""
    msg = str(error)
    head = f"profiles.{profile}."
    key, rest = None, msg
    if msg.startswith(head) and ": " in msg:
        key, rest = msg[len(head):].split(": ", 1)
    if key is None:
        return ConfigError(f"{path}: {msg}", file=str(path), profile=profile)
    origin = key_origin(origins, key, default=profile)
    if origin == "command line":
        text = f"{path}: {key}: {rest} (set on the command line over profile {profile})"
    elif origin != profile:
        text = f"{path}: profiles.{origin}.{key}: {rest} (profile {profile} inherits it from {origin})"
    else:
        text = f"{path}: profiles.{profile}.{key}: {rest}"
    return ConfigError(text, file=str(path), profile=profile, origin=origin, key=key)


HARNESS_KEYS = ("devices",)
"""Profile keys that the harness reads and a study's Settings never sees (`harness_options`)."""


def harness_options(path, profile: str, overrides: Optional[dict] = None) -> dict:
    """The harness keys of profile `profile` (HARNESS_KEYS), validated, with their defaults:

    devices   how many devices each run's steps use (sph.parallel; default 1); `make DEVICES=N`
              (lab.experiment --devices N) overrides it"""
    mapping = profile_mapping(path, profile, overrides)
    devices = mapping.get("devices", 1)
    if not (isinstance(devices, int) and not isinstance(devices, bool) and devices >= 1):
        raise ConfigError(f"{path}: profiles.{profile}.devices: must be a whole number >= 1, got {devices!r}",
                          file=str(path), profile=profile, key="devices")
    return {"devices": devices}


def load_profile(cls, path, profile: str, overrides: Optional[dict] = None):
    """Build `cls` from profile `profile` of a YAML file (see `profile_mapping`; the HARNESS_KEYS
    left out). Errors name the file, the profile the offending key is written in (an inherited one
    if the requested profile does not set it) and the key path, e.g. ``config.yaml:
    profiles.paper.dx[0]: ... (profile smoke inherits it from paper)``; the ConfigError carries them
    as `file`, `profile`, `origin`, `key`."""
    mapping, origins = profile_mapping(path, profile, overrides, with_origins=True)
    mapping = {k: v for k, v in mapping.items() if k not in HARNESS_KEYS}
    try:
        return from_mapping(cls, mapping, f"profiles.{profile}")
    except ConfigError as e:
        if getattr(e, "disagreeing", None):
            raise locate_disagreement(e, path, profile, mapping, origins) from None
        raise locate(e, path, profile, origins) from None


_MISSING = object()


def _value_at(mapping, parts: tuple):
    for p in parts:
        if isinstance(p, int):
            if not isinstance(mapping, list) or p >= len(mapping):
                return _MISSING
            mapping = mapping[p]
        else:
            if not isinstance(mapping, dict) or p not in mapping:
                return _MISSING
            mapping = mapping[p]
    return mapping


def committed_profile(path, profile: str) -> Optional[dict]:
    """The merged mapping of `profile` in the last committed version of the YAML file `path` (git
    HEAD), or None (no git, not committed, no such profile then)."""
    import subprocess

    path = Path(path).resolve()
    try:
        top = subprocess.run(["git", "-C", str(path.parent), "rev-parse", "--show-toplevel"], capture_output=True,
                             text=True, timeout=10)
        if top.returncode != 0:
            return None
        rel = path.relative_to(Path(top.stdout.strip()).resolve()).as_posix()
        shown = subprocess.run(["git", "-C", top.stdout.strip(), "show", f"HEAD:{rel}"], capture_output=True,
                               text=True, timeout=10)
        if shown.returncode != 0:
            return None
        return _resolve_profile((yaml.safe_load(shown.stdout) or {}).get("profiles") or {}, profile, ())[0]
    except Exception:  # noqa: BLE001  (a best-effort hint: any failure means "unknown")
        return None


def locate_disagreement(error: ConfigError, path, profile: str, mapping: dict, origins: dict) -> ConfigError:
    """A rule between several keys broken (`require_agree`): "<file>: profiles.<p>.<key>: <rule> (the
    keys that disagree: <key> = <v> (changed since the last commit); <other> = <w>)", the key changed
    since the last commit first (then the one written closest to the profile asked for: the command
    line, the profile itself, an inherited one), only keys the config writes (all if it writes none)."""
    head = f"profiles.{profile}."
    keys = [k[len(head):] if k.startswith(head) else k for k in error.disagreeing]
    msg = str(error)
    rest = msg.split(": ", 1)[1] if ": " in msg else msg
    written = [k for k in keys if _value_at(mapping, key_path(k)) is not _MISSING] or keys
    committed = committed_profile(path, profile)
    closeness = {"command line": 0, profile: 1}

    def changed(k):
        return committed is not None and _value_at(committed, key_path(k)) != _value_at(mapping, key_path(k))

    order = sorted(written, key=lambda k: (not changed(k), closeness.get(key_origin(origins, k, profile), 2),
                                           keys.index(k)))

    def full(k):
        origin = key_origin(origins, k, default=profile)
        return k if origin == "command line" else f"profiles.{origin}.{k}"

    def value(k):
        v = _value_at(mapping, key_path(k))
        return f"{k} = {v!r}" if v is not _MISSING else f"{k} (default)"

    tag = (" (set on the command line)" if key_origin(origins, order[0]) == "command line"
           else " (changed since the last commit)" if changed(order[0]) else "")
    named = "; ".join([value(order[0]) + tag] + [value(k) for k in order[1:]])
    text = f"{path}: {full(order[0])}: {rest} (the keys that disagree: {named})"
    return ConfigError(text, file=str(path), profile=profile, origin=key_origin(origins, order[0], profile),
                       key=order[0])


def _paths(d: dict, prefix: tuple = ()):
    for k, v in d.items():
        yield prefix + (k,), v
        if isinstance(v, dict):
            yield from _paths(v, prefix + (k,))


def _merge_origins(origins: dict, own: dict, name: str) -> dict:
    """Origins after merging mapping `own` (written in profile `name`) over the recorded ones: every
    path of `own` is `name`'s; a non-mapping value of `own` replaces whatever the parent had below it."""
    out = dict(origins)
    for p, v in _paths(own):
        if not isinstance(v, dict):
            for q in [q for q in out if len(q) > len(p) and q[:len(p)] == p]:
                del out[q]
        out[p] = name
    return out


def _resolve_profile(profiles: dict, name: str, seen: tuple):
    """(mapping, origins) of profile `name`, following `inherit`."""
    if name not in profiles:
        raise ConfigError(f"profiles.{name}: no such profile (known: {', '.join(sorted(profiles))})")
    if name in seen:
        raise ConfigError(f"profiles.{name}.inherit: circular inheritance {' -> '.join(seen + (name,))}")
    if not isinstance(profiles[name] or {}, dict):
        raise ConfigError(f"profiles.{name}: expected a mapping, got {profiles[name]!r}")
    own = dict(profiles[name] or {})
    parent = own.pop("inherit", None)
    if parent is None:
        return own, _merge_origins({}, own, name)
    if not isinstance(parent, str):
        raise ConfigError(f"profiles.{name}.inherit: expected a profile name, got {parent!r}")
    base, origins = _resolve_profile(profiles, parent, seen + (name,))
    return merge(base, own), _merge_origins(origins, own, name)
