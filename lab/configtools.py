"""Frozen-dataclass configs from plain mappings (YAML), validated on construction.

`from_mapping(Cls, data, where)` rejects unknown keys and wrong types with a message that names the
full key path (e.g. ``numerics.cfl``), and recurses into nested config dataclasses. Classes add
their own value checks in ``__post_init__`` by raising ``ConfigError`` via ``require`` (both from
the core's `sph.errors`, re-exported here for the experiments' settings). `load_profile(cls, path,
profile)` reads one profile of a YAML file with ``inherit`` between profiles, its errors naming the
file, the profile that wrote the bad key and the key.
"""
import dataclasses
import math
import re
import types
import typing
from pathlib import Path
from typing import Optional

import yaml

from sph.errors import ConfigError, is_finite_number, require, require_finite  # noqa: F401  (re-exported)


NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
"""What a method, case or run name may be: it becomes a folder or file name (results/<profile>/<study>/
<method>_dx0.02), so nothing that can leave that folder (a slash, "..") or needs quoting."""


def require_name(value, key: str) -> str:
    """`value` if it is a name (NAME: letters, digits, _ and -, not starting with a digit or -), else a
    ConfigError naming `key`."""
    if not isinstance(value, str) or not NAME.fullmatch(value):
        raise ConfigError(f"{key}: {value!r} is not a name: it becomes a folder name, so use letters, digits, "
                          "_ and - only, starting with a letter or _ (e.g. tvf_fine)")
    return value


def require_agree(cond: bool, keys, msg: str) -> None:
    """Like `require`, for a rule between several keys (e.g. ghia_re and material.eta): the error
    names all of `keys`; `load_profile` puts the one changed since the last commit (else the one
    written closest to the profile asked for) first, so a user who edited one of them is not told
    to change the other."""
    if not cond:
        e = ConfigError(f"{keys[0]}: {msg}")
        e.disagreeing = tuple(keys)
        raise e


def _check_type(value, tp, key, allow_inf: bool = False):
    """`value` checked against type hint `tp` (and converted: a list to a tuple, a mapping to its
    dataclass, an int to a float); a ConfigError naming `key` when it does not match."""
    origin = typing.get_origin(tp)
    if tp is typing.Any:
        return value
    if origin in (typing.Union, types.UnionType):
        return _check_union(value, tp, key, allow_inf)
    if origin is tuple:
        return _check_tuple(value, typing.get_args(tp), key, allow_inf)
    if dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        return from_mapping(tp, value, key)
    if tp is float:
        return _check_float(value, key, allow_inf)
    if tp in (int, bool, str):
        return _check_scalar(value, tp, key)
    if isinstance(tp, type) and not isinstance(value, tp):
        raise ConfigError(f"{key}: expected {tp.__name__}, got {value!r}")
    return value


def _check_union(value, tp, key, allow_inf):
    """`value` as the first member of union `tp` it matches (None for an Optional's None); the
    member's own error when the union has one non-None member."""
    args = typing.get_args(tp)
    if value is None and type(None) in args:
        return None
    errors = []
    for a in args:
        if a is type(None):
            continue
        try:
            return _check_type(value, a, key, allow_inf)
        except ConfigError as e:
            errors.append(e)
    if len(errors) == 1:
        raise errors[0]
    raise ConfigError(f"{key}: {value!r} does not match {tp}")


def _check_tuple(value, args, key, allow_inf):
    """A list or tuple checked entry by entry against tuple[args] (fixed length, or tuple[X, ...])."""
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{key}: expected a list, got {value!r}")
    if len(args) == 2 and args[1] is Ellipsis:
        return tuple(_check_type(v, args[0], f"{key}[{i}]", allow_inf) for i, v in enumerate(value))
    if len(args) != len(value):
        raise ConfigError(f"{key}: expected {len(args)} entries, got {len(value)}")
    return tuple(_check_type(v, a, f"{key}[{i}]", allow_inf) for i, (v, a) in enumerate(zip(value, args)))


def _check_float(value, key, allow_inf):
    """A number (not a bool) as a float; NaN never, +-inf only with `allow_inf`."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{key}: expected a number, got {value!r}")
    if math.isnan(value) or (math.isinf(value) and not allow_inf):
        raise ConfigError(f"{key}: must be a finite number, got {value!r}"
                          + ("" if math.isnan(value) else " (use a large finite value)"))
    return float(value)


_SCALAR_NAMES = {int: "an integer", bool: "true or false", str: "a string"}


def _check_scalar(value, tp, key):
    """An int, bool or str `value` of exactly type `tp` (a bool is not an integer here)."""
    if not isinstance(value, tp) or (tp is int and isinstance(value, bool)):
        raise ConfigError(f"{key}: expected {_SCALAR_NAMES[tp]}, got {value!r}")
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
        # a field may accept +-inf with dataclasses.field(metadata={"allow_inf": True}); NaN never
        allow_inf = bool(fields[name].metadata.get("allow_inf", False))
        kwargs[name] = _check_type(value, hints[name], prefix + name, allow_inf)
        if name == "name" and hints[name] is str:  # a method's / case's name becomes a folder name
            require_name(kwargs[name], prefix + name)
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

            def local(k):
                return prefix + (k[len(section):] if k.startswith(section) else k)

            err = ConfigError(local(msg))
            if getattr(e, "disagreeing", None):
                err.disagreeing = tuple(local(k) for k in e.disagreeing)
            raise err from None
        raise


class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader that refuses a key written twice in one mapping (plain YAML keeps the last
    value silently), naming the key and both lines."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise ConfigError(f"{self.name}:{line}: key {key!r} is written twice in one mapping (lines {seen[key]} "
                                  f"and {line}); YAML would keep only the last: delete one", file=str(self.name))
            seen[key] = line
        return super().construct_mapping(node, deep=deep)


def load_yaml(path) -> dict:
    """Read a YAML mapping; an empty file is an empty mapping; a key written twice in one mapping is
    refused, naming both lines."""
    path = Path(path)
    try:
        with path.open() as f:
            data = yaml.load(f, Loader=_UniqueKeyLoader)
    except yaml.YAMLError as e:
        raise yaml_error(path, e) from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{path}: cannot read the config file ({type(e).__name__}: {e})", file=str(path)) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    return data


def yaml_error(path, e: "yaml.YAMLError") -> ConfigError:
    """A YAML syntax error as one ConfigError "<file>:<line>: <problem> (<context>); <hint>", the line
    (1-based) where the parser found the problem."""
    mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
    where = f"{path}:{mark.line + 1}" if mark is not None else str(path)
    problem = " ".join(str(getattr(e, "problem", None) or e).split())
    context = " ".join(str(getattr(e, "context", None) or "").split())
    cmark = getattr(e, "context_mark", None)
    if context and cmark is not None and mark is not None and cmark.line != mark.line:
        context += f" started at line {cmark.line + 1}"
    hint = "YAML indents with spaces, never tabs" if "'\\t'" in problem or "\t" in problem \
        else "check the brackets, quotes and indentation there"
    text = f"{where}: YAML syntax error: {problem}" + (f" ({context})" if context else "") + f"; {hint}"
    return ConfigError(text, file=str(path))


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
