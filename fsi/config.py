"""Typed, validated case configuration loaded from YAML.

A case is a tree of frozen dataclasses (:class:`Case`); the YAML file mirrors it key for key and
every key is optional (defaults are the study's values, ../shared/MODEL.md). Precedence: defaults
< YAML < ``--set key.path=value`` overrides. Unknown keys, wrong types and out-of-range values
raise :class:`ConfigError` naming the file, the key and what is expected, before anything is
computed. The schema is documented in docs/configuration.md.
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Union

import yaml

from geometry import stenosis as stenosis_geometry


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats: plain ``4e6`` and ``1.0e-3`` are numbers."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?|\.[0-9_]+(?:[eE][-+]?[0-9]+)?"
               r"|[0-9][0-9_]*[eE][-+]?[0-9]+|\.inf|\.Inf|\.INF|\.nan|\.NaN|\.NAN)$"),
    list("-+0123456789."),
)


def parse_yaml(text: str):
    return yaml.load(text, Loader=_Loader)  # noqa: S506 (a SafeLoader subclass)


class ConfigError(Exception):
    """A configuration value is wrong: ``source: key: expected ..., got ...``."""

    def __init__(self, source: str, key: str, expected: str, got: Any = dataclasses.MISSING):
        self.source, self.key, self.expected, self.got = source, key, expected, got
        message = f"{source}: {key}: expected {expected}"
        if got is not dataclasses.MISSING:
            message += f", got {got!r}"
        super().__init__(message)


def _check(default: Any, check: typing.Callable[[Any], bool], expected: str) -> Any:
    """A dataclass field with a range check and the words that describe the allowed range."""
    return field(default=default, metadata={"check": check, "expected": expected})


def positive(default: float, unit: str = "") -> Any:
    return _check(default, lambda v: v > 0, f"a positive number{unit}")


def non_negative(default: float, unit: str = "") -> Any:
    return _check(default, lambda v: v >= 0, f"a number >= 0{unit}")


def at_least(default: int, low: int) -> Any:
    return _check(default, lambda v: v >= low, f"an integer >= {low}")


def open_interval(default: float, low: float, high: float, unit: str = "") -> Any:
    return _check(default, lambda v: low < v < high, f"a number in ({low}, {high}){unit}")


# --------------------------------------------------------------------------------------------
# Geometry and mesh


@dataclass(frozen=True)
class StenosisGeometry:
    """The stenosed carotid of MODEL.md §1 (geometry/stenosis.py has the profiles)."""

    kind: Literal["stenosis"] = "stenosis"
    length: float = positive(0.02, " (m)")
    height: float = positive(0.007, " (m)")
    wall_thickness: float = positive(0.001, " (m)")
    stenosis_length: float = positive(0.01, " (m)")
    stenosis_degree: float = open_interval(0.5, 0.0, 1.0)
    cap_thickness: float = positive(0.0005, " (m)")
    lipid_length: float = positive(0.006, " (m)")
    plaque_sides: tuple[Literal["bottom", "top"], ...] = ("bottom",)


@dataclass(frozen=True)
class ChannelGeometry:
    """A straight rigid channel for verification cases (geometry/channel.py)."""

    kind: Literal["channel"] = "channel"
    length: float = positive(0.02, " (m)")
    height: float = positive(0.007, " (m)")


MESH_LEVELS = {"coarse": 0, "medium": 1, "fine": 2}


@dataclass(frozen=True)
class MeshSettings:
    """gmsh sizes of the coarse mesh: ``size`` away from, ``local_size`` at the plaque (or the
    obstacle); ``level`` adds uniform refinements (medium = coarse × 4, fine = coarse × 16)."""

    level: Literal["coarse", "medium", "fine"] = "coarse"
    size: float = positive(6.0e-4, " (m)")
    local_size: float = positive(2.2e-4, " (m)")

    @property
    def refinements(self) -> int:
        return MESH_LEVELS[self.level]


# --------------------------------------------------------------------------------------------
# Fluid


@dataclass(frozen=True)
class Newtonian:
    model: Literal["newtonian"] = "newtonian"
    viscosity: float = positive(0.0035, " (Pa s)")


@dataclass(frozen=True)
class Carreau:
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)²)^((n − 1)/2)."""

    model: Literal["carreau"] = "carreau"
    mu_0: float = positive(0.0456, " (Pa s)")
    mu_inf: float = positive(0.0032, " (Pa s)")
    relaxation_time: float = positive(10.03, " (s)")
    power_index: float = positive(0.344)


Rheology = Union[Newtonian, Carreau]


@dataclass(frozen=True)
class InletPulse:
    """Inlet traction h(t) = (A/2)(1 − cos(2π t / T)) e_x for t ≤ T, 0 after (MODEL.md §2)."""

    kind: Literal["traction_pulse"] = "traction_pulse"
    amplitude: float = positive(1200.0, " (Pa, peak)")
    duration: float = positive(0.005, " (s)")


@dataclass(frozen=True)
class Outlet:
    """Traction-free outlet; ``backflow_stabilization`` β ≥ 0 scales the inflow-penalising term."""

    backflow_stabilization: float = non_negative(1.0)


@dataclass(frozen=True)
class SolverSettings:
    """Newton tolerances and the PETSc options of one sub-solver (its prefix is fixed)."""

    rtol: float = positive(1.0e-9)
    atol: float = positive(1.0e-10)
    max_iterations: int = at_least(25, 1)
    petsc_options: dict[str, Union[str, int, float]] = field(
        default_factory=lambda: {
            "ksp_type": "preonly",
            "pc_type": "lu",
            "pc_factor_mat_solver_type": "mumps",
        }
    )


@dataclass(frozen=True)
class Fluid:
    density: float = positive(1060.0, " (kg/m^3)")
    rheology: Rheology = field(default_factory=Newtonian)
    inlet: InletPulse = field(default_factory=InletPulse)
    outlet: Outlet = field(default_factory=Outlet)
    quadrature_degree: int = at_least(4, 1)
    solver: SolverSettings = field(default_factory=SolverSettings)


# --------------------------------------------------------------------------------------------
# Structure


@dataclass(frozen=True)
class Material:
    """St. Venant–Kirchhoff material of one structure region (MODEL.md §3)."""

    law: Literal["svk"] = "svk"
    density: float = positive(1200.0, " (kg/m^3)")
    young_modulus: float = positive(1.6e6, " (Pa)")
    poisson_ratio: float = open_interval(0.45, -1.0, 0.5)


@dataclass(frozen=True)
class Structure:
    """``fixed_wall``: vessel wall held, plaque deforms; ``moving_wall``: wall and plaque deform;
    ``rigid``: no structure solve (fluid-only runs)."""

    mode: Literal["fixed_wall", "moving_wall", "rigid"] = "fixed_wall"
    wall: Material = field(default_factory=lambda: Material(young_modulus=4.0e6))
    cap: Material = field(default_factory=Material)
    lipid: Material = field(default_factory=Material)
    quadrature_degree: int = at_least(4, 1)
    solver: SolverSettings = field(default_factory=SolverSettings)


# --------------------------------------------------------------------------------------------
# Time, coupling, output


@dataclass(frozen=True)
class TimeSegment:
    """Steps of ``dt`` until time ``until`` (the last step of a segment ends exactly on it)."""

    until: float = positive(0.4, " (s)")
    dt: float = positive(5.0e-3, " (s)")


@dataclass(frozen=True)
class Time:
    """The step schedule; the default is the study's: 5 ms to 0.4 s, then 10 ms to 0.8 s."""

    end: float = positive(0.8, " (s)")
    scheme: Literal["backward_euler", "bdf2"] = "bdf2"
    schedule: tuple[TimeSegment, ...] = (TimeSegment(0.4, 5.0e-3), TimeSegment(0.8, 1.0e-2))


@dataclass(frozen=True)
class Coupling:
    """Dirichlet–Neumann iterations per step (MODEL.md §5)."""

    acceleration: Literal["constant", "aitken", "iqn-ils"] = "aitken"
    tolerance: float = positive(1.0e-6)
    max_iterations: int = at_least(50, 1)
    initial_relaxation: float = _check(0.5, lambda v: 0 < v <= 1, "a number in (0, 1]")
    iqn_reuse: int = at_least(4, 0)
    iqn_filter: float = positive(1.0e-8)


@dataclass(frozen=True)
class Output:
    fields: Literal["xdmf", "vtx"] = "xdmf"
    fields_every: int = at_least(1, 1)
    checkpoint_every: int = at_least(10, 1)
    report_times: tuple[float, ...] = (0.01, 0.02, 0.05, 0.1, 0.8)


@dataclass(frozen=True)
class Case:
    name: str = "case"
    geometry: Union[StenosisGeometry, ChannelGeometry] = field(default_factory=StenosisGeometry)
    mesh: MeshSettings = field(default_factory=MeshSettings)
    fluid: Fluid = field(default_factory=Fluid)
    structure: Structure = field(default_factory=Structure)
    time: Time = field(default_factory=Time)
    coupling: Coupling = field(default_factory=Coupling)
    output: Output = field(default_factory=Output)


# --------------------------------------------------------------------------------------------
# Loading


def load(path: str | Path, overrides: typing.Sequence[str] = ()) -> Case:
    """Read a case from YAML, apply ``key.path=value`` overrides, build and validate it."""
    path = Path(path)
    source = str(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(source, "<file>", "a readable YAML file", e.strerror) from None
    try:
        data = parse_yaml(text)
    except yaml.YAMLError as e:
        raise ConfigError(source, "<file>", f"valid YAML ({e})".replace("\n", " ")) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(source, "<top level>", "a mapping of sections", type(data).__name__)
    overridden = apply_overrides(data, overrides)
    return from_dict(data, source, overridden)


def apply_overrides(data: dict, overrides: typing.Sequence[str]) -> set[str]:
    """Set ``key.path=value`` (value parsed as YAML) in ``data``; return the keys set."""
    keys = set()
    for item in overrides:
        key, sep, text = item.partition("=")
        if not sep or not key or any(not part for part in key.split(".")):
            raise ConfigError("--set", item, "key.path=value")
        try:
            value = parse_yaml(text)
        except yaml.YAMLError:
            raise ConfigError("--set", key, "a YAML value", text) from None
        node = data
        parts = key.split(".")
        for i, part in enumerate(parts[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError("--set", ".".join(parts[: i + 1]), "a section", child)
            node = child
        node[parts[-1]] = value
        keys.add(key)
    return keys


def from_dict(data: dict, source: str = "<dict>", overridden: set[str] | None = None) -> Case:
    """Build and validate a :class:`Case` from a plain dict (as read from YAML)."""
    overridden = overridden or set()
    try:
        case = _build(Case, data, "")
        validate(case)
    except ConfigError as e:
        # Name the command line, not the file, when the bad value came from --set.
        origin = "--set" if any(e.key == k or e.key.startswith(k + ".") for k in overridden) else source
        raise ConfigError(origin, e.key, e.expected, e.got) from None
    return case


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
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin is tuple:
        return "a list of " + _describe(typing.get_args(tp)[0]).removeprefix("a ").removeprefix("an ")
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(a) for a in typing.get_args(tp))
    return str(tp)


def _build(tp: Any, value: Any, key: str) -> Any:
    """Convert a YAML value to type ``tp`` strictly (no str→bool, no bool→number, no float→int)."""
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError("", key or "<top level>", "a mapping", value)
        fields = {f.name: f for f in dataclasses.fields(tp)}
        unknown = sorted(set(value) - set(fields))
        if unknown:
            k = f"{key}.{unknown[0]}" if key else str(unknown[0])
            raise ConfigError("", k, "one of the keys " + ", ".join(fields), "unknown key")
        kwargs = {}
        hints = typing.get_type_hints(tp)
        for name, f in fields.items():
            if name not in value:
                continue
            sub = f"{key}.{name}" if key else name
            v = _build(hints[name], value[name], sub)
            if "check" in f.metadata and not f.metadata["check"](v):
                raise ConfigError("", sub, f.metadata["expected"], v)
            kwargs[name] = v
        return tp(**kwargs)
    if origin in (Union, types.UnionType):
        options = typing.get_args(tp)
        if all(dataclasses.is_dataclass(o) for o in options):
            return _build_tagged(options, value, key)
        for option in options:
            try:
                return _build(option, value, key)
            except ConfigError:
                continue
        raise ConfigError("", key, _describe(tp), value)
    if origin is Literal:
        if value not in typing.get_args(tp) or isinstance(value, bool):
            raise ConfigError("", key, _describe(tp), value)
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise ConfigError("", key, _describe(tp), value)
        item = typing.get_args(tp)[0]
        return tuple(_build(item, v, f"{key}[{i}]") for i, v in enumerate(value))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError("", key, "a mapping", value)
        value_type = typing.get_args(tp)[1]
        return {str(k): _build(value_type, v, f"{key}.{k}") for k, v in value.items()}
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError("", key, "a number", value)
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError("", key, "an integer", value)
        return value
    if tp is str or tp is bool:
        if not isinstance(value, tp):
            raise ConfigError("", key, _describe(tp), value)
        return value
    raise TypeError(f"unsupported configuration type {tp!r} at {key}")


def _build_tagged(options: tuple, value: Any, key: str) -> Any:
    """Choose among dataclasses by their first field, a Literal tag (``kind``, ``model``)."""
    tag = dataclasses.fields(options[0])[0].name
    choices = {typing.get_args(typing.get_type_hints(o)[tag])[0]: o for o in options}
    if not isinstance(value, dict):
        raise ConfigError("", key, "a mapping", value)
    chosen = value.get(tag, typing.get_args(typing.get_type_hints(options[0])[tag])[0])
    if chosen not in choices:
        raise ConfigError("", f"{key}.{tag}", "one of " + ", ".join(map(repr, choices)), chosen)
    return _build(choices[chosen], value, key)


def validate(case: Case) -> None:
    """Checks that involve several keys (single values are checked while building)."""
    g = case.geometry
    if isinstance(g, StenosisGeometry):
        if len(set(g.plaque_sides)) != len(g.plaque_sides) or not g.plaque_sides:
            raise ConfigError("", "geometry.plaque_sides", "'bottom', 'top' or both, once each",
                              list(g.plaque_sides))
        if g.stenosis_length >= g.length:
            raise ConfigError("", "geometry.stenosis_length",
                              f"less than geometry.length = {g.length} m", g.stenosis_length)
        plaque = stenosis_geometry.plaque_height(g)
        if g.cap_thickness >= plaque:
            raise ConfigError("", "geometry.cap_thickness",
                              f"less than the plaque height {plaque:g} m (stenosis_degree × height"
                              " / plaque sides)", g.cap_thickness)
        if g.lipid_length >= g.stenosis_length:
            raise ConfigError("", "geometry.lipid_length",
                              f"less than geometry.stenosis_length = {g.stenosis_length} m",
                              g.lipid_length)
        thinnest = stenosis_geometry.min_cap_thickness(g)
        if thinnest < g.cap_thickness * (1 - 1e-4):
            raise ConfigError("", "geometry.lipid_length",
                              "a lipid pool short enough that the fibrous cap is nowhere thinner"
                              f" than cap_thickness = {g.cap_thickness} m (it would be"
                              f" {thinnest:.3g} m)", g.lipid_length)
    elif case.structure.mode != "rigid":
        raise ConfigError("", "structure.mode", f"'rigid' for geometry.kind '{g.kind}'"
                          " (it has no structure)", case.structure.mode)
    if case.mesh.local_size > case.mesh.size:
        raise ConfigError("", "mesh.local_size", f"at most mesh.size = {case.mesh.size} m",
                          case.mesh.local_size)

    schedule = case.time.schedule
    if not schedule:
        raise ConfigError("", "time.schedule", "at least one {until, dt} segment", [])
    for i in range(1, len(schedule)):
        if schedule[i].until <= schedule[i - 1].until:
            raise ConfigError("", f"time.schedule[{i}].until",
                              f"greater than time.schedule[{i - 1}].until = "
                              f"{schedule[i - 1].until} s", schedule[i].until)
    if schedule[-1].until < case.time.end * (1 - 1e-12):
        raise ConfigError("", f"time.schedule[{len(schedule) - 1}].until",
                          f"at least time.end = {case.time.end} s", schedule[-1].until)

    # Sub-solvers must be well below the coupling tolerance or the coupling stalls near it.
    for name in ("fluid", "structure"):
        rtol = getattr(case, name).solver.rtol
        if rtol > case.coupling.tolerance / 10:
            raise ConfigError("", f"{name}.solver.rtol",
                              f"at most coupling.tolerance / 10 = {case.coupling.tolerance / 10:g}",
                              rtol)


def to_dict(case: Case) -> dict:
    """The resolved configuration as plain YAML-ready data (tuples as lists)."""

    def plain(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v

    return plain(dataclasses.asdict(case))


def dump(case: Case, path: str | Path) -> None:
    Path(path).write_text(yaml.safe_dump(to_dict(case), sort_keys=False))
