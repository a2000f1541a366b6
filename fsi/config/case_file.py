"""A case file to a :class:`Case` and back: :func:`load` reads, builds and validates one
(:func:`from_dict` from data already read, with a ``pressure_file`` or ``flow_rate_file``
inlet's rows read from its CSV file), :func:`to_dict`, :func:`to_yaml` and :func:`dump` write
the resolved configuration.
"""

from __future__ import annotations

import copy as copy_module
import dataclasses
import typing
from pathlib import Path
from typing import Any

from fsi.config.boundary_data import WaveformError, read_waveform
from fsi.config.case import Case
from fsi.config.domain import is_axisymmetric
from fsi.config.fluid_section import WAVEFORM_FILES
from fsi.config.reader import (
    MAX_FILE_BYTES,
    ConfigError,
    apply_overrides,
    build,
    dump_yaml,
    read_case_file,
)
from fsi.config.validation import validate

RUN_CONFIG_BYTES = 4 * MAX_FILE_BYTES
"""The size limit of a run's own ``config.yaml`` (:func:`load` with ``run_config=True``): its
CSV inlet is written out as a table, and a CSV file of the case-file limit takes up to about
twice as much as YAML."""


def load(
    path: str | Path, overrides: typing.Sequence[str] = (), *, run_config: bool = False
) -> Case:
    """Read a case from YAML, apply ``key.path=value`` overrides, build and validate it.

    ``run_config``: ``path`` is a run folder's own ``config.yaml`` (written by ``fsi run``),
    read up to :data:`RUN_CONFIG_BYTES` rather than a case file's limit.

    Every failure is a :class:`ConfigError` naming the file (or ``--set``) and the key: what
    :func:`fsi.config.reader.read_case_file` refuses (unreadable, too large, not UTF-8, invalid
    or too deeply nested YAML, a repeated key) and whatever :func:`from_dict` refuses.
    """
    return loader(path, run_config=run_config)(overrides)


def loader(
    path: str | Path, *, run_config: bool = False
) -> typing.Callable[[typing.Sequence[str]], Case]:
    """:func:`load` of ``path`` with the overrides it is called with, the file read and
    parsed once (a sweep loads it with each combination's values). Raises the
    :class:`ConfigError` of reading the file at once; the function returned raises those of
    the overrides and the case."""
    data = read_case_file(path, RUN_CONFIG_BYTES if run_config else MAX_FILE_BYTES)

    def load_with(overrides: typing.Sequence[str] = ()) -> Case:
        copy = copy_module.deepcopy(data)
        overridden = apply_overrides(copy, overrides)
        return from_dict(copy, str(path), overridden)

    return load_with


def from_dict(data: dict, source: str = "<dict>", overridden: set[str] | None = None) -> Case:
    """Build and validate a :class:`Case` from a plain dict (as read from YAML).

    ``overridden``: the keys :func:`fsi.config.reader.apply_overrides` set (and the sections
    it created); an error at one of them, below one (``time.schedule[0].dt`` below
    ``time.schedule``) or about a whole section one changed (``mesh``'s cell count after
    ``--set mesh.size=...``) names ``--set`` instead of ``source``."""
    overridden = overridden or set()
    try:
        case = build(Case, data, "")
        case = _read_inlet_file(case, source, overridden)
        validate(case)
    except ConfigError as e:
        from_command_line = any(
            e.key == k or e.key.startswith((k + ".", k + "[")) or k.startswith(e.key + ".")
            for k in overridden
        )
        raise e.from_source("--set" if from_command_line else source) from None
    return case


def _read_inlet_file(case: Case, source: str, overridden: set[str]) -> Case:
    """``case`` with a ``pressure_file`` or ``flow_rate_file`` inlet's rows read into its
    ``table`` (other inlets unchanged). ``file`` is relative to the folder of ``source`` (the
    case file), or to the current directory when ``--set`` gave it (or ``source`` is not a
    file: ``<dict>``); the path kept in the case is the one opened."""
    inlet = case.fluid.inlet
    if not isinstance(inlet, WAVEFORM_FILES):
        return case
    if inlet.table:
        raise ConfigError(
            "",
            "fluid.inlet.table",
            reason=f"not a key of kind '{inlet.kind}' "
            "(its rows come from fluid.inlet.file; use kind "
            f"'{inlet.as_table().kind}' to give them inline)",
        )
    if not inlet.file:
        raise ConfigError(
            "",
            "fluid.inlet.file",
            f"the name of a CSV file of rows t, {inlet.quantity} (relative to the case file's "
            "folder)",
        )
    from_command_line = bool({"fluid", "fluid.inlet", "fluid.inlet.file"} & overridden)
    path = Path(inlet.file)
    if not path.is_absolute() and not from_command_line and source not in ("<dict>", "--set"):
        path = Path(source).parent / path
    try:
        rows = read_waveform(path, inlet.quantity, axisymmetric=is_axisymmetric(case.geometry))
    except OSError as e:
        raise ConfigError(
            "", "fluid.inlet.file", reason=f"cannot read {path} ({e.strerror or type(e).__name__})"
        ) from None
    except WaveformError as e:
        raise ConfigError("", "fluid.inlet.file", reason=str(e)) from None
    inlet = dataclasses.replace(inlet, file=str(path), table=rows)
    return dataclasses.replace(case, fluid=dataclasses.replace(case.fluid, inlet=inlet))


def to_dict(case: Case) -> dict:
    """The resolved configuration as plain YAML-ready data (tuples as lists); a
    ``pressure_file`` (``flow_rate_file``) inlet as the ``pressure_table``
    (``flow_rate_table``) of its rows and other keys, so that :func:`load` of the data needs no
    CSV file and gives the same P(t) (Q(t))."""

    def plain(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v

    data = plain(dataclasses.asdict(case))
    inlet = case.fluid.inlet
    if isinstance(inlet, WAVEFORM_FILES):  # self-contained: the rows, not the file
        data["fluid"]["inlet"] = plain(dataclasses.asdict(inlet.as_table()))
    return data


def to_yaml(case: Case) -> str:
    """The resolved configuration as YAML text (``fsi run`` writes it as DIR/config.yaml)."""
    return dump_yaml(to_dict(case))


def differences(stored: dict, now: dict, prefix: str = "") -> list[str]:
    """The key paths where the configuration data ``now`` differs from ``stored`` (both as
    :func:`to_dict` gives them; keys ``stored`` lacks, written before they existed, are left
    out; a mapping is compared key by key)."""
    found = []
    for key, value in now.items():
        path = f"{prefix}{key}"
        if key not in stored:
            continue
        if isinstance(value, dict) and isinstance(stored[key], dict):
            found += differences(stored[key], value, path + ".")
        elif stored[key] != value:
            found.append(path)
    return found


def dump(case: Case, path: str | Path) -> None:
    """Write :func:`to_yaml` of ``case`` to the file ``path``."""
    Path(path).write_text(to_yaml(case))
