"""Strict reading of case data: bounded YAML, refused duplicate keys, and a typed builder.

A case file is read as at most :data:`MAX_FILE_BYTES` of UTF-8 YAML nested at most
:data:`MAX_YAML_DEPTH` levels, without repeated keys (:func:`read_case_file`);
``--set key.path=value`` overrides are applied to the data (:func:`apply_overrides`); then
:func:`build` turns the data into the frozen dataclasses of :mod:`fsi.config` strictly: no
unknown key, no str→bool, no bool→number, no float→int, no inf or nan, every range check of a
field (:func:`checked` and its shorthands) applied. Every failure is a :class:`ConfigError`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import reprlib
import stat
import types
import typing
from dataclasses import field
from pathlib import Path
from typing import Any, Literal, Union

import yaml

MAX_FILE_BYTES = 1 << 20
"""A case file is at most 1 MiB (the shipped ones are < 4 kB; a 50,000-row pressure table fits)."""

MAX_YAML_DEPTH = 32
"""Nesting levels of YAML lists and mappings (the schema needs 6): deeper is refused before
PyYAML's recursive composer reaches Python's recursion limit."""


class YAMLTooDeep(yaml.YAMLError):
    """YAML nested more than :data:`MAX_YAML_DEPTH` levels, at ``line`` (1-based)."""

    def __init__(self, mark: yaml.Mark):
        self.line, self.column = mark.line + 1, mark.column + 1
        super().__init__(
            f"YAML nested more than {MAX_YAML_DEPTH} levels deep (line {self.line},"
            f" column {self.column})"
        )


_FLOAT = re.compile(
    r"^[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?|\.[0-9_]+(?:[eE][-+]?[0-9]+)?"
    r"|[0-9][0-9_]*[eE][-+]?[0-9]+|\.inf|\.Inf|\.INF|\.nan|\.NaN|\.NAN)$"
)
"""YAML 1.2 floats: PyYAML's YAML 1.1 ones need a dot (``1.0e-3``); these take ``4e6`` too."""

_BASE_60 = re.compile(r"^[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?$")
"""YAML 1.1's base-60 numbers (``1:30`` = 90), which YAML 1.2 dropped: read as strings, so a
``time.end: 1:30`` is refused as not a number instead of being taken for 90 s."""


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats (plain ``4e6`` and ``1.0e-3`` are numbers),
    no base-60 numbers (``1:30`` is a string) and a nesting limit of :data:`MAX_YAML_DEPTH`
    levels."""

    _depth = 0

    def resolve(self, kind, value, implicit):
        if kind is yaml.ScalarNode and implicit[0] and _BASE_60.match(value):
            return "tag:yaml.org,2002:str"
        return super().resolve(kind, value, implicit)

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise YAMLTooDeep(self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))


class _Dumper(yaml.SafeDumper):
    """PyYAML's safe dumper that also quotes the strings :class:`_Loader` reads as floats
    (``'1e-3'``): PyYAML's own resolvers take ``1e-3`` for a string and would write it plain,
    so that a run's ``config.yaml`` would read back a number where the run had a string."""


_Dumper.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))


def dump_yaml(data: Any) -> str:
    """``data`` as YAML text that :func:`parse_yaml` reads back as the same data (every string
    that would read as a number, a bool, null or a date is quoted), keys in their order."""
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False)


def parse_yaml(text: str, source: str = "<string>", key: str = ""):
    """The data of one YAML document (safe types only).

    Raises ``yaml.YAMLError`` for invalid YAML (:class:`YAMLTooDeep` for nesting deeper than
    :data:`MAX_YAML_DEPTH`), and :class:`ConfigError` (``source``, the key path below ``key``)
    for a key that a mapping repeats: PyYAML would silently keep the last one.
    """
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _refuse_duplicate_keys(node, source, key)
        try:
            return loader.construct_document(node)
        except (ValueError, TypeError, OverflowError) as e:  # 5000 digits, month 13, ...
            raise yaml.YAMLError(f"a value cannot be read: {shorten(str(e))}") from None
    finally:
        loader.dispose()


def _refuse_duplicate_keys(root: yaml.Node, source: str, root_key: str) -> None:
    """Walk the composed YAML graph once per node (aliases share nodes, so an alias "bomb" is
    not expanded) and raise :class:`ConfigError` at the first mapping that repeats a key."""
    seen: set[int] = set()
    stack = [(root, root_key)]
    while stack:
        node, key = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            first: dict[tuple, yaml.Mark] = {}
            for key_node, value_node in node.value:
                name = str(key_node.value) if isinstance(key_node, yaml.ScalarNode) else "?"
                sub = f"{key}.{name}" if key else name
                identity = (
                    (key_node.tag, name)
                    if isinstance(key_node, yaml.ScalarNode)
                    else (id(key_node),)
                )
                mark = key_node.start_mark
                if identity in first:
                    a = first[identity]
                    where = (
                        f"lines {a.line + 1} and {mark.line + 1}"
                        if a.line != mark.line
                        else f"line {a.line + 1}, columns {a.column + 1} and {mark.column + 1}"
                    )
                    raise ConfigError(source, sub, reason=f"duplicate key ({where})")
                first[identity] = mark
                stack.append((value_node, sub))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, f"{key}[{i}]") for i, item in enumerate(node.value))


class ConfigError(Exception):
    """A configuration value is wrong: ``source: key: expected ..., got ...``, or, when there
    is no single expected value, ``source: key: reason`` (``source: reason`` without a key)."""

    def __init__(
        self,
        source: str,
        key: str,
        expected: str = "",
        got: Any = dataclasses.MISSING,
        reason: str | None = None,
    ):
        self.source, self.key, self.expected, self.got = source, key, expected, got
        self.reason = reason
        where = f"{source}: {key}" if key else source
        if reason is not None:
            message = f"{where}: {reason}"
        else:
            message = f"{where}: expected {expected}"
            if got is not dataclasses.MISSING:
                message += f", got {_show(got)}"
        super().__init__(message)

    def from_source(self, source: str) -> ConfigError:
        """The same error, attributed to ``source`` (a file, or ``--set``)."""
        return ConfigError(source, self.key, self.expected, self.got, self.reason)


def shorten(text: str, limit: int = 80) -> str:
    """``text``, or its start and its length when longer than ``limit`` (a 1 MB formula)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxtuple, _REPR.maxdict = 2, 8, 8, 8
_REPR.maxlong, _REPR.maxother = 40, 40


def _show(value: Any) -> str:
    """A value for a message, bounded: a string by :func:`_shorten`, containers by
    ``reprlib`` (YAML aliases can make a list of 10⁹ shared items, too long to ``repr``)."""
    return shorten(repr(value) if isinstance(value, str) else _REPR.repr(value))


def _finite(value: Any) -> bool:
    """False only for a float inf or nan (the builder refuses those for every number)."""
    return not isinstance(value, float) or math.isfinite(value)


def checked(
    default: Any, check: typing.Callable[[Any], bool], expected: str, unit: str = ""
) -> Any:
    """A dataclass field with a range check and the words that describe the allowed range.

    ``check`` returns whether a value is allowed; it may instead raise ``ValueError`` whose
    ``reason`` (or message) is added to the error. A non-finite number is refused before
    ``check`` sees it, with ``expected`` as "a finite ...". ``unit`` is the value's unit
    (:func:`unit_of`), shown in the message after ``expected``.
    """
    return field(default=default, metadata={"check": check, "expected": expected, "unit": unit})


def _with_unit(expected: str, unit: str) -> str:
    return f"{expected} ({unit})" if unit else expected


def positive(default: float, unit: str = "", note: str = "") -> Any:
    """A :func:`checked` field whose value must be > 0, in ``unit`` (``note`` follows it in
    the message)."""
    return checked(default, lambda v: v > 0, _with_unit("a positive number", unit + note), unit)


def non_negative(default: float, unit: str = "", note: str = "") -> Any:
    """A :func:`checked` field whose value must be >= 0, in ``unit``."""
    return checked(default, lambda v: v >= 0, _with_unit("a number >= 0", unit + note), unit)


def at_least(default: int, low: int) -> Any:
    """A :func:`checked` integer field whose value must be >= ``low``."""
    return checked(default, lambda v: v >= low, f"an integer >= {low}")


def open_interval(default: float, low: float, high: float, unit: str = "") -> Any:
    """A :func:`checked` field whose value must lie in (``low``, ``high``), in ``unit``."""
    expected = _with_unit(f"a number in ({low}, {high})", unit)
    return checked(default, lambda v: low < v < high, expected, unit)


def unit_of(section: Any, key: str) -> str:
    """The unit of the number at dotted ``key`` below the dataclass instance ``section`` (e.g.
    a Case and ``geometry.cap_thickness`` → "m"), as its field declares it; "" for a number
    without a unit or a key that is not such a field."""
    *parents, name = key.split(".")
    for part in parents:
        section = getattr(section, part, None)
    if not dataclasses.is_dataclass(section):
        return ""
    for f in dataclasses.fields(section):
        if f.name == name:
            return f.metadata.get("unit", "")
    return ""


def read_case_file(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> dict:
    """The data of the YAML case file ``path`` (``{}`` for an empty file).

    Raises :class:`ConfigError` naming the file for an unreadable file, one larger than
    ``max_bytes`` or not UTF-8 text, invalid or too deeply nested YAML, a repeated key, or a
    top level that is not a mapping.
    """
    source = str(path)
    try:
        if not stat.S_ISREG(Path(path).stat().st_mode):  # a FIFO would block for ever
            raise ConfigError(source, "", reason="not a regular file: not a case file")
        with Path(path).open("rb") as f:
            raw = f.read(max_bytes + 1)  # bounded: /dev/zero is refused, not read for ever
    except OSError as e:
        raise ConfigError(source, "<file>", "a readable YAML file", e.strerror) from None
    if len(raw) > max_bytes:
        raise ConfigError(source, "", reason=f"larger than {max_bytes} bytes: not a case file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(
            source,
            "",
            reason=f"not UTF-8 text (byte 0x{raw[e.start]:02x} at "
            f"offset {e.start}): not a case file",
        ) from None
    try:
        data = parse_yaml(text, source)
    except YAMLTooDeep as e:
        raise ConfigError(source, "", reason=str(e)) from None
    except yaml.YAMLError as e:
        raise ConfigError(source, "<file>", f"valid YAML ({e})".replace("\n", " ")) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(source, "<top level>", "a mapping of sections", type(data).__name__)
    return data


def apply_overrides(data: dict, overrides: typing.Sequence[str]) -> set[str]:
    """Set ``key.path=value`` (value parsed as YAML) in ``data``; return the keys set and the
    sections the overrides created (a section not in ``data`` comes from the command line)."""
    keys = set()
    for item in overrides:
        key, sep, text = item.partition("=")
        if not sep or not key or any(not part for part in key.split(".")):
            raise ConfigError("--set", shorten(item), "key.path=value")
        try:
            value = parse_yaml(text, "--set", key)
        except YAMLTooDeep as e:
            raise ConfigError("--set", key, reason=str(e)) from None
        except yaml.YAMLError:
            raise ConfigError("--set", key, "a YAML value", text) from None
        node = data
        parts = key.split(".")
        for i, part in enumerate(parts[:-1]):
            if part not in node:
                keys.add(".".join(parts[: i + 1]))
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError("--set", ".".join(parts[: i + 1]), "a section", child)
            node = child
        node[parts[-1]] = value
        keys.add(key)
    return keys


def _describe(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is str:
        return "a string"
    if tp is bool:
        return "true or false"
    if tp is type(None):
        return "null"
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin is tuple:
        return "a list of " + _describe(typing.get_args(tp)[0]).removeprefix("a ").removeprefix(
            "an "
        )
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(a) for a in typing.get_args(tp))
    return str(tp)


@functools.cache
def _type_hints(tp: Any) -> dict[str, Any]:
    """``typing.get_type_hints`` of the schema's dataclass ``tp``, worked out once: it
    evaluates every annotation anew on each call, most of the time of building a Case."""
    return typing.get_type_hints(tp)


def build(tp: Any, value: Any, key: str) -> Any:
    """Convert a YAML value to type ``tp`` strictly (no str→bool, no bool→number, no float→int,
    no inf or nan for any number)."""
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return _build_dataclass(tp, value, key)
    if origin in (Union, types.UnionType):
        return _build_union(tp, value, key)
    if origin is Literal:
        if value not in typing.get_args(tp) or isinstance(value, bool):
            raise ConfigError("", key, _describe(tp), value)
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise ConfigError("", key, _describe(tp), value)
        item = typing.get_args(tp)[0]
        return tuple(build(item, v, f"{key}[{i}]") for i, v in enumerate(value))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError("", key, "a mapping", value)
        value_type = typing.get_args(tp)[1]
        return {str(k): build(value_type, v, f"{key}.{k}") for k, v in value.items()}
    if tp is float:
        return _build_float(value, key)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError("", key, "an integer", value)
        return value
    if tp is str or tp is bool:
        if not isinstance(value, tp):
            raise ConfigError("", key, _describe(tp), value)
        return value
    if tp is type(None):
        if value is not None:
            raise ConfigError("", key, "null", value)
        return None
    raise TypeError(f"unsupported configuration type {tp!r} at {key}")


def _build_dataclass(tp: Any, value: Any, key: str) -> Any:
    """The dataclass ``tp`` from the mapping ``value``: no unknown keys, each field built with
    :func:`build` and passed through its ``check`` (metadata), absent fields left to defaults."""
    if not isinstance(value, dict):
        raise ConfigError("", key or "<top level>", "a mapping", value)
    fields = {f.name: f for f in dataclasses.fields(tp)}
    unknown = sorted(set(value) - set(fields), key=str)
    if unknown:
        k = f"{key}.{unknown[0]}" if key else str(unknown[0])
        raise ConfigError("", k, "one of the keys " + ", ".join(fields), "unknown key")
    kwargs = {}
    hints = _type_hints(tp)
    for name, f in fields.items():
        if name not in value:
            continue
        sub = f"{key}.{name}" if key else name
        expected = f.metadata.get("expected")
        if hints[name] is float and expected is not None and not _finite(value[name]):
            # "a positive number (s)" -> "a finite positive number (s)"
            raise ConfigError("", sub, "a finite " + expected.removeprefix("a "), value[name])
        v = build(hints[name], value[name], sub)
        if "check" in f.metadata:
            try:
                allowed = f.metadata["check"](v)
            except ValueError as e:
                raise ConfigError("", sub, f"{expected} ({getattr(e, 'reason', e)})", v) from None
            if not allowed:
                raise ConfigError("", sub, expected, v)
        kwargs[name] = v
    return tp(**kwargs)


def _build_union(tp: Any, value: Any, key: str) -> Any:
    """``value`` as the first option of the union ``tp`` that accepts it (dataclasses chosen by
    their tag, see :func:`_build_tagged`); no inf or nan where a number is allowed."""
    options = typing.get_args(tp)
    if all(dataclasses.is_dataclass(o) for o in options):
        return _build_tagged(options, value, key)
    if float in options and not _finite(value):
        raise ConfigError("", key, "a finite number", value)
    others = [o for o in options if o is not type(None)]
    if isinstance(value, list) and len(others) == 1 and typing.get_origin(others[0]) is tuple:
        return build(others[0], value, key)  # an optional list: its item's own message
    if isinstance(value, dict) and len(others) == 1 and dataclasses.is_dataclass(others[0]):
        return build(others[0], value, key)  # an optional section: its keys' own messages
    for option in options:
        try:
            return build(option, value, key)
        except ConfigError:
            continue
    raise ConfigError("", key, _describe(tp), value)


def _build_float(value: Any, key: str) -> float:
    """``value`` (an int or float, not a bool) as a finite float."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError("", key, "a number", value)
    try:
        number = float(value)
    except OverflowError:  # an integer of hundreds of digits
        number = math.inf
    if not math.isfinite(number):
        raise ConfigError("", key, "a finite number", value)
    return number


def _build_tagged(options: tuple, value: Any, key: str) -> Any:
    """Choose among dataclasses by their first field, a Literal tag (``kind``, ``model``)."""
    tag = dataclasses.fields(options[0])[0].name
    choices = {typing.get_args(_type_hints(o)[tag])[0]: o for o in options}
    if not isinstance(value, dict):
        raise ConfigError("", key, "a mapping", value)
    chosen = value.get(tag, typing.get_args(_type_hints(options[0])[tag])[0])
    if chosen not in choices:
        raise ConfigError("", f"{key}.{tag}", "one of " + ", ".join(map(repr, choices)), chosen)
    return build(choices[chosen], value, key)
