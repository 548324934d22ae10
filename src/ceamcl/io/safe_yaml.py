"""YAML for small configuration files (ROS map YAML, route files), read as ROS reads them and
without the ways a tiny file can exhaust memory.

* **No aliases.** ``&anchor``/``*alias`` let 500 bytes expand to gigabytes (a "billion laughs");
  map and route files never need them, so an alias is refused with its line.
* **A size bound.** The file (or pipe) may hold at most :data:`MAX_BYTES` (1 MiB).
* **Numbers as ROS reads them.** ROS parses map YAML with yaml-cpp (YAML 1.2), where
  ``5e-2``, ``1e3`` and ``.5`` are numbers; PyYAML's YAML 1.1 resolver reads the first two as
  text. The loader resolves YAML 1.2 core-schema floats as well.
* **Encodings.** Text that is not UTF-8 is refused naming the file, not a traceback.
* **Unique keys.** YAML requires a mapping's keys to be unique; PyYAML keeps the last value of
  a repeated key and yaml-cpp's choice has varied by version, so ``resolution`` given twice
  could mean 0.05 here and 0.5 in Nav2. A repeated key is refused naming it and its lines.

Errors are :class:`~ceamcl.errors.CeamclError` subclasses chosen by the caller (``error``).
"""

from __future__ import annotations

import os
import re
from typing import Any

import yaml

from ceamcl.errors import CeamclError, ConfigError
from ceamcl.io import streams

__all__ = ["MAX_BYTES", "load_yaml_file", "load_yaml_text"]

#: Largest YAML configuration file read (maps and routes are a few hundred bytes).
MAX_BYTES = 1 << 20

_FLOAT_12 = re.compile(
    r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?$"
    r"|^[-+]?\.(?:inf|Inf|INF)$|^\.(?:nan|NaN|NAN)$"
)


class _Loader(yaml.SafeLoader):
    """SafeLoader without aliases and with YAML 1.2 floats."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None,
                None,
                f"aliases (*{event.anchor}) are not accepted here",
                event.start_mark,
            )
        return super().compose_node(parent, index)

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        """A mapping whose keys are unique, as YAML requires (PyYAML keeps the last value)."""
        if isinstance(node, yaml.MappingNode):
            first: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = (key_node.tag, self.construct_object(key_node, deep=True))
                try:
                    seen = first.get(key)
                except TypeError:  # an unhashable key: PyYAML's own error names it
                    continue
                if seen is not None:
                    raise yaml.constructor.ConstructorError(
                        None,
                        None,
                        f"duplicate key {key[1]!r} (first on line {seen}); expected each key "
                        "once in a mapping",
                        key_node.start_mark,
                    )
                first[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def yaml_problem(exc: yaml.YAMLError) -> tuple[int | None, str]:
    """The line (1-based, ``None`` if unknown) and the one-line problem of a YAML error
    (PyYAML's own text draws the line with a caret over several lines)."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
    return (None if mark is None else mark.line + 1), problem


def load_yaml_text(text: str, where: str, error: type[CeamclError] = ConfigError) -> Any:
    """Parse ``text`` (from ``where``, a file name for messages)."""
    try:
        return yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        line, problem = yaml_problem(exc)
        raise error(
            f"{where}{'' if line is None else f':{line}'}: not valid YAML: {problem}"
        ) from None
    except RecursionError:
        raise error(f"{where}: not valid YAML: nested too deeply") from None


def load_yaml_file(
    path: str | os.PathLike[str], what: str, error: type[CeamclError] = ConfigError
) -> Any:
    """Read and parse a YAML ``what`` ("map YAML file", "route file") at ``path``.

    Raises ``error`` naming the file when it is missing, unreadable, larger than
    :data:`MAX_BYTES`, not UTF-8, not YAML, or uses an alias.
    """
    try:
        data = streams.read_all(path, MAX_BYTES, what)
    except FileNotFoundError:
        raise error(f"{path}: cannot read the {what}: {what} not found") from None
    except IsADirectoryError:
        raise error(f"{path}: expected a {what}, got a folder") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    except streams.StreamError as exc:
        raise error(str(exc)) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}: not UTF-8 text (byte {data[exc.start]:#04x} at offset {exc.start}); "
            f"expected a {what} in UTF-8 text"
        ) from None
    return load_yaml_text(text, str(path), error)
