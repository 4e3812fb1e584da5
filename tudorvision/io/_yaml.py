"""YAML helpers shared by the calibration and sequence readers.

:func:`read_yaml` reports syntax errors with the file and line and gives a
``line_of(keys)`` function so that semantic errors can point at a line too;
:func:`dump_yaml` writes numeric lists in flow style for readable files.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from .._checks import TudorVisionError, check_array, check_transform

__all__ = ["read_yaml", "dump_yaml", "YamlContext"]


def read_yaml(path: Path):
    """Load a YAML file; errors name the file and the line.

    Returns
    -------
    data : object
        The parsed document.
    line_of : callable
        ``line_of(keys) -> int or None``: 1-based line of the value at the
        key path ``keys`` (strings for mappings, ints for lists), or of its
        deepest existing ancestor. Used to point semantic errors at a line.

    Raises
    ------
    TudorVisionError
        If the file is absent, unreadable or not valid YAML.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TudorVisionError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TudorVisionError(f"{path}: cannot read ({exc})") from None
    try:
        data = yaml.safe_load(text)
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else str(path)
        what = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise TudorVisionError(f"{where}: malformed YAML: {what}") from None

    def line_of(keys) -> int | None:
        node = root
        line = node.start_mark.line + 1 if node is not None else None
        for key in keys:
            nxt = None
            if isinstance(node, yaml.MappingNode):
                for k, v in node.value:
                    if getattr(k, "value", None) == str(key):
                        nxt = v
                        break
            elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) \
                    and 0 <= key < len(node.value):
                nxt = node.value[key]
            if nxt is None:
                break
            node = nxt
            line = node.start_mark.line + 1
        return line

    return data, line_of


class YamlContext:
    """Builds errors of the form ``file:line: key.path: message``."""

    def __init__(self, path, line_of):
        self.path = path
        self.line_of = line_of

    def error(self, keys, msg) -> TudorVisionError:
        line = self.line_of(keys) if self.line_of else None
        where = f"{self.path}:{line}" if line else str(self.path)
        name = ".".join(str(k) for k in keys)
        return TudorVisionError(f"{where}: {name}: {msg}" if name else f"{where}: {msg}")

    def array(self, value, keys, shape):
        want = "(" + ", ".join("N" if n is None else str(n) for n in shape) + ")"
        try:
            np.asarray(value, dtype=np.float64)
        except (ValueError, TypeError):
            text = repr(value) if len(repr(value)) < 80 else repr(value)[:77] + "..."
            raise self.error(keys, f"expected shape {want} of numbers, got {text}") from None
        try:
            return check_array(value, ".".join(map(str, keys)), shape)
        except (ValueError, TypeError) as exc:
            raise self.error(keys, str(exc).split(": ", 1)[-1]) from None

    def transform(self, value, keys):
        T = self.array(value, keys, (4, 4))
        try:
            return check_transform(T, "T")
        except ValueError as exc:
            raise self.error(keys, str(exc).split(": ", 1)[-1]) from None


class _FlowDumper(yaml.SafeDumper):
    """Writes number lists (rows of K, dist, T) on one line for readability."""

    def ignore_aliases(self, data):
        return True


def _repr_list(dumper, data):
    flow = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_FlowDumper.add_representer(list, _repr_list)
_FlowDumper.add_representer(tuple, _repr_list)
_FlowDumper.add_multi_representer(np.generic, lambda d, x: d.represent_data(x.item()))
_FlowDumper.add_representer(np.ndarray, lambda d, x: d.represent_data(x.tolist()))


def dump_yaml(data) -> str:
    """YAML text with numeric lists in flow style and keys in insertion order.

    NumPy scalars and arrays are written as plain numbers and lists.

    Examples
    --------
    >>> print(dump_yaml({"K": np.eye(2), "n": np.int64(3)}), end="")
    K:
    - [1.0, 0.0]
    - [0.0, 1.0]
    n: 3
    """
    return yaml.dump(data, Dumper=_FlowDumper, sort_keys=False, default_flow_style=False,
                     allow_unicode=True)
