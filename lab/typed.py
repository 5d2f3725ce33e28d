"""Frozen-dataclass configs from plain mappings, validated on construction.

`from_mapping(Cls, data, where)` rejects unknown keys and wrong types with a message that names the
full key path (e.g. ``numerics.cfl``), and recurses into nested config dataclasses. Classes add
their own value checks in ``__post_init__`` by raising ``ConfigError`` via ``require`` (from the
core's `sph.errors`), `require_agree` for a rule between keys, `require_name` for a name that
becomes a folder. `to_mapping` is the plain-dict view back, `merge` the key-by-key merge of two
mappings.
"""
import dataclasses
import math
import re
import types
import typing

from sph.errors import ConfigError


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
