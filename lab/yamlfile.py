"""YAML config files read strictly: a key written twice in one mapping is refused (YAML would keep
the last silently), a syntax error is one line naming the file, the line and a hint."""
from pathlib import Path

import yaml

from sph.errors import ConfigError


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
