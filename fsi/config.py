"""Typed, validated case configuration loaded from YAML.

A case is a tree of frozen dataclasses (:class:`Case`); the YAML file mirrors it key for key and
every key is optional (defaults are the study's values, ../shared/MODEL.md). Precedence: defaults
< YAML < ``--set key.path=value`` overrides. Unknown keys, wrong types and out-of-range values
raise :class:`ConfigError` naming the file, the key and what is expected, before anything is
computed. The schema is documented in docs/configuration.md.

What a configuration may not do (each refused with a :class:`ConfigError`): hold a number that
is not finite; nest YAML deeper than :data:`MAX_YAML_DEPTH` levels or repeat a key; exceed
:data:`MAX_FILE_BYTES`; give PETSc any option outside the allow-list of
:func:`check_petsc_options` (no viewers, monitors, Python types, options files or file paths);
ask for more than ``time.max_steps`` steps or, by :func:`estimated_cells`, more than
``mesh.max_cells`` triangles; give an inlet formula longer than :data:`MAX_FORMULA_LENGTH`
characters or one that fails at t = 0 or at a step time of the schedule; give a
``pressure_file`` inlet whose CSV file cannot be read or is not a waveform (:func:`read_waveform`).
"""

from __future__ import annotations

import dataclasses
import math
import re
import reprlib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Union

import yaml

from fsi.timestepping import steps
from geometry import stenosis as stenosis_geometry
from geometry import turek_hron as turek_hron_geometry

MAX_FILE_BYTES = 1 << 20
"""A case file is at most 1 MiB (the shipped ones are < 4 kB; a 50,000-row pressure table fits)."""

MAX_YAML_DEPTH = 32
"""Nesting levels of YAML lists and mappings (the schema needs 6): deeper is refused before
PyYAML's recursive composer reaches Python's recursion limit."""


class YAMLTooDeep(yaml.YAMLError):
    """YAML nested more than :data:`MAX_YAML_DEPTH` levels, at ``line`` (1-based)."""

    def __init__(self, mark: yaml.Mark):
        self.line, self.column = mark.line + 1, mark.column + 1
        super().__init__(f"YAML nested more than {MAX_YAML_DEPTH} levels deep (line {self.line},"
                         f" column {self.column})")


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats (plain ``4e6`` and ``1.0e-3`` are numbers) and
    a nesting limit of :data:`MAX_YAML_DEPTH` levels."""

    _depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise YAMLTooDeep(self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?|\.[0-9_]+(?:[eE][-+]?[0-9]+)?"
               r"|[0-9][0-9_]*[eE][-+]?[0-9]+|\.inf|\.Inf|\.INF|\.nan|\.NaN|\.NAN)$"),
    list("-+0123456789."),
)


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
            raise yaml.YAMLError(f"a value cannot be read: {_shorten(str(e))}") from None
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
                identity = (key_node.tag, name) if isinstance(key_node, yaml.ScalarNode) else (
                    id(key_node),)
                mark = key_node.start_mark
                if identity in first:
                    a = first[identity]
                    where = (f"lines {a.line + 1} and {mark.line + 1}" if a.line != mark.line else
                             f"line {a.line + 1}, columns {a.column + 1} and {mark.column + 1}")
                    raise ConfigError(source, sub, reason=f"duplicate key ({where})")
                first[identity] = mark
                stack.append((value_node, sub))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, f"{key}[{i}]") for i, item in enumerate(node.value))


class ConfigError(Exception):
    """A configuration value is wrong: ``source: key: expected ..., got ...``, or, when there
    is no single expected value, ``source: key: reason`` (``source: reason`` without a key)."""

    def __init__(self, source: str, key: str, expected: str = "",
                 got: Any = dataclasses.MISSING, reason: str | None = None):
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


def _shorten(text: str, limit: int = 80) -> str:
    """``text``, or its start and its length when longer than ``limit`` (a 1 MB formula)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxtuple, _REPR.maxdict = 2, 8, 8, 8
_REPR.maxlong, _REPR.maxother = 40, 40


def _show(value: Any) -> str:
    """A value for a message, bounded: a string by :func:`_shorten`, containers by
    ``reprlib`` (YAML aliases can make a list of 10⁹ shared items, too long to ``repr``)."""
    return _shorten(repr(value) if isinstance(value, str) else _REPR.repr(value))


def _finite(value: Any) -> bool:
    """False only for a float inf or nan (the builder refuses those for every number)."""
    return not isinstance(value, float) or math.isfinite(value)


def _check(default: Any, check: typing.Callable[[Any], bool], expected: str) -> Any:
    """A dataclass field with a range check and the words that describe the allowed range.

    ``check`` returns whether a value is allowed; it may instead raise ``ValueError`` whose
    ``reason`` (or message) is added to the error. A non-finite number is refused before
    ``check`` sees it, with ``expected`` as "a finite ...".
    """
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


@dataclass(frozen=True)
class TurekHronGeometry:
    """The Turek–Hron benchmark (../shared/reference/turek_hron.md, geometry/turek_hron.py): a
    channel ``[0, length] × [0, height]``, a rigid cylinder and an elastic flag of
    ``flag_length`` (from the cylinder's rightmost point to the tip) × ``flag_thickness`` centred
    on the cylinder's axis. Defaults are the benchmark's (tip and point A at x = 0.6)."""

    kind: Literal["turek_hron"] = "turek_hron"
    length: float = positive(2.5, " (m)")
    height: float = positive(0.41, " (m)")
    cylinder_centre: tuple[float, ...] = (0.2, 0.2)
    cylinder_radius: float = positive(0.05, " (m)")
    flag_length: float = positive(0.35, " (m)")
    flag_thickness: float = positive(0.02, " (m)")


MESH_LEVELS = {"coarse": 0, "medium": 1, "fine": 2}


@dataclass(frozen=True)
class MeshSettings:
    """gmsh sizes of the coarse mesh: ``size`` away from, ``local_size`` at the plaque (or the
    obstacle); ``level`` adds uniform refinements (medium = coarse × 4, fine = coarse × 16).

    ``max_cells``: validation refuses a mesh whose :func:`estimated_cells` exceeds it, before
    gmsh starts (memory grows with the cells: the fine stenosis, 51k triangles, took ~0.9 GB
    in a serial coupled run, ~18 kB per triangle, so the default 10⁶ is ~18 GB)."""

    level: Literal["coarse", "medium", "fine"] = "coarse"
    size: float = positive(6.0e-4, " (m)")
    local_size: float = positive(2.2e-4, " (m)")
    max_cells: int = at_least(1_000_000, 1)

    @property
    def refinements(self) -> int:
        return MESH_LEVELS[self.level]


def quadrature(default: int) -> Any:
    """A quadrature degree in [1, :data:`MAX_QUADRATURE_DEGREE`]."""
    return _check(default, lambda v: 1 <= v <= MAX_QUADRATURE_DEGREE,
                  f"an integer in [1, {MAX_QUADRATURE_DEGREE}]")


MAX_QUADRATURE_DEGREE = 20
"""The highest quadrature degree a case may set. The shipped cases use 4 (exact for the P2 SVK
residual); a triangle rule of degree q has about (q/2 + 1)² points, which the form compiler
unrolls into the generated C and assembly visits in every cell, so cost grows as q² (UFL's own
choice of 22 for the Carreau Jacobian assembled 5× slower than 4, DESIGN.md) and degree 100000
never finishes compiling (issue #14). 20 leaves room for convergence studies."""


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


@dataclass(frozen=True)
class CarreauYasuda:
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)^a)^((n − 1)/a). Defaults: blood (Cho & Kensey 1991, as
    used by Johnston et al. 2004)."""

    model: Literal["carreau_yasuda"] = "carreau_yasuda"
    mu_0: float = positive(0.056, " (Pa s)")
    mu_inf: float = positive(0.00345, " (Pa s)")
    relaxation_time: float = positive(1.902, " (s)")
    power_index: float = positive(0.22)
    yasuda_exponent: float = positive(1.25)


@dataclass(frozen=True)
class Cross:
    """μ(s) = μ∞ + (μ0 − μ∞) / (1 + (λ s)^m). Defaults: blood (Johnston et al. 2004)."""

    model: Literal["cross"] = "cross"
    mu_0: float = positive(0.0364, " (Pa s)")
    mu_inf: float = positive(0.0035, " (Pa s)")
    relaxation_time: float = positive(0.38, " (s)")
    exponent: float = positive(1.45)


@dataclass(frozen=True)
class PowerLaw:
    """μ(s) = K (s² + s0²)^((n − 1)/2): the power law K s^(n−1) with the shear rate smoothly
    floored at s0, so μ(0) = K s0^(n−1) is finite. Defaults: blood, K and n of Johnston et al.
    (2004); s0 = 0.0169 1/s puts μ(0) at their cap of 0.056 Pa s."""

    model: Literal["power_law"] = "power_law"
    consistency: float = positive(0.017, " (Pa s^n)")
    power_index: float = positive(0.708)
    shear_rate_floor: float = positive(0.0169, " (1/s)")


@dataclass(frozen=True)
class Casson:
    """Casson's √τ = √τy + √(μc s), regularised after Papanastasiou:
    μ(s) = (√μc + √(τy / s) (1 − exp(−√(m s))))², finite at s = 0 (μ(0) = (√μc + √(τy m))²).
    Defaults: typical blood values (τy 5 mPa, μc 3.5 mPa s) and m = 100 s."""

    model: Literal["casson"] = "casson"
    viscosity: float = positive(0.0035, " (Pa s)")
    yield_stress: float = positive(0.005, " (Pa)")
    regularization: float = positive(100.0, " (s)")


Rheology = Union[Newtonian, Carreau, CarreauYasuda, Cross, PowerLaw, Casson]


@dataclass(frozen=True)
class InletPulse:
    """Inlet traction h(t) = (A/2)(1 − cos(2π t / T)) e_x for t ≤ T, 0 after (MODEL.md §2)."""

    kind: Literal["traction_pulse"] = "traction_pulse"
    amplitude: float = positive(1200.0, " (Pa, peak)")
    duration: float = positive(0.005, " (s)")


_FORMULA_NAMES = ("sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "abs", "min", "max")

MAX_FORMULA_LENGTH = 2000
"""Characters of an inlet formula: ample for a pulse of several harmonics, and short enough
that parsing and compiling it are instant."""

MAX_FORMULA_DEPTH = 100
"""Levels of nested operations in an inlet formula (a formula of several harmonics needs
about 10): deeper is refused the same way on every Python (3.11 cannot compile a few hundred
levels, 3.13 can)."""


class FormulaError(ValueError):
    """An inlet formula is not an allowed expression (``t`` None), or its value at time ``t``
    is not a finite real number: division by zero, a math domain error (``log(0)``,
    ``sqrt(-1)``), an overflow, a complex result, inf or nan. ``reason`` says which."""

    def __init__(self, formula: str, reason: str, t: float | None = None):
        self.formula, self.reason, self.t = formula, reason, t
        at = "" if t is None else f" at t = {t:.6g} s"
        super().__init__(f"formula {_shorten(repr(formula), 60)}{at}: {reason}")


def _depth(tree) -> int:
    """The depth of a syntax tree (without recursion: the tree may be deep)."""
    import ast

    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return deepest


def time_function(formula: str) -> typing.Callable[[float], float]:
    """``formula``, an arithmetic expression in the time ``t`` (s), as a function of t.

    Allowed: numbers, ``t``, ``pi``, ``e``, ``+ - * / ** %``, parentheses, comparisons (true = 1,
    e.g. ``600*(1 - cos(2*pi*t/0.005))*(t <= 0.005)``) and the functions sin, cos, tan, exp, log,
    sqrt, tanh, abs, min, max, in at most :data:`MAX_FORMULA_LENGTH` characters. Raises
    :class:`FormulaError` (a ValueError) for anything else (names, attributes, strings, nesting
    too deep to compile). The function returned returns a finite float or raises
    :class:`FormulaError` naming the formula and t; it raises nothing else.
    """
    import ast

    if len(formula) > MAX_FORMULA_LENGTH:
        raise FormulaError(formula, f"longer than {MAX_FORMULA_LENGTH} characters")
    try:
        tree = ast.parse(formula, mode="eval")
    except SyntaxError as e:
        raise FormulaError(formula, f"not an expression: {e.msg}") from None
    except (ValueError, RecursionError, MemoryError) as e:  # null bytes; nesting
        raise FormulaError(formula, f"not an expression: {_nesting(e)}") from None
    if _depth(tree) > MAX_FORMULA_DEPTH:
        raise FormulaError(formula, f"nested more than {MAX_FORMULA_DEPTH} levels deep")
    allowed = (ast.Expression, ast.BinOp, ast.UnaryOp, ast.Compare, ast.Call, ast.Name, ast.Load,
               ast.Constant, ast.operator, ast.unaryop, ast.cmpop)
    for node in ast.walk(tree):
        if not isinstance(node, allowed) or isinstance(node, (ast.MatMult, ast.BitAnd, ast.BitOr,
                                                              ast.BitXor, ast.LShift, ast.RShift,
                                                              ast.FloorDiv, ast.Invert, ast.Not,
                                                              ast.Is, ast.IsNot, ast.In,
                                                              ast.NotIn)):
            raise FormulaError(formula, f"{type(node).__name__} is not allowed")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise FormulaError(formula, f"{_shorten(repr(node.value), 40)} is not a number")
            try:
                node.value = float(node.value)  # float powers overflow instead of running forever
            except OverflowError:
                raise FormulaError(formula, "a number too large for a float") from None
        if isinstance(node, ast.Name) and node.id not in ("t", "pi", "e", *_FORMULA_NAMES):
            raise FormulaError(formula, f"unknown name {node.id!r}")
        if isinstance(node, ast.Call) and (node.keywords or not isinstance(node.func, ast.Name)
                                           or node.func.id not in _FORMULA_NAMES):
            raise FormulaError(formula, "only calls of " + ", ".join(_FORMULA_NAMES))
    try:
        code = compile(tree, "<formula>", "eval")
    except (ValueError, RecursionError, MemoryError) as e:
        raise FormulaError(formula, f"cannot be compiled: {_nesting(e)}") from None
    names = {"__builtins__": {}, "pi": math.pi, "e": math.e, "abs": abs, "min": min, "max": max}
    names.update({f: getattr(math, f) for f in _FORMULA_NAMES if hasattr(math, f)})

    def value(t: float) -> float:
        try:
            result = eval(code, names, {"t": float(t)})  # noqa: S307 (checked above)
        except ZeroDivisionError:
            raise FormulaError(formula, "division by zero", t) from None
        except OverflowError:
            raise FormulaError(formula, "overflow", t) from None
        except (ArithmeticError, ValueError, TypeError, RecursionError, MemoryError) as e:
            raise FormulaError(formula, str(e) or type(e).__name__, t) from None
        if isinstance(result, complex):  # a negative number to a fractional power
            raise FormulaError(formula, f"complex result {result}", t)
        result = float(result)
        if not math.isfinite(result):
            raise FormulaError(formula, f"the result is {result}", t)
        return result

    return value


def _nesting(error: Exception) -> str:
    """Words for a parser/compiler failure: nesting too deep (recursion, memory) or its message."""
    if isinstance(error, (RecursionError, MemoryError)):
        return "nested too deeply"
    return str(error)


def _is_time_formula(text: str) -> bool:
    """True, or :class:`FormulaError` saying why ``text`` is not an allowed formula."""
    time_function(text)
    return True


@dataclass(frozen=True)
class InletPressure:
    """Inlet normal traction σ n = −P(t) n (P pushes blood in) with P (Pa) a formula in t."""

    kind: Literal["pressure"] = "pressure"
    formula: str = _check("0", _is_time_formula, "an expression in t (numbers, + - * / ** %,"
                          " comparisons, pi, e, " + ", ".join(_FORMULA_NAMES) + ")")


def _is_time_table(rows: tuple) -> bool:
    return (len(rows) >= 1 and all(len(r) == 2 for r in rows)
            and all(b[0] > a[0] for a, b in zip(rows, rows[1:])))


def _period() -> Any:
    return non_negative(0.0, " (s; 0: no repetition)")


@dataclass(frozen=True)
class InletPressureTable:
    """Inlet normal traction σ n = −P(t) n from rows [t (s), P (Pa)]: linear between rows,
    constant beyond the first and last; with ``period`` T > 0, P(t) = P_table(t mod T), and the
    rows must cover [0, T] (checked by :func:`validate`)."""

    kind: Literal["pressure_table"] = "pressure_table"
    table: tuple[tuple[float, ...], ...] = _check(
        ((0.0, 0.0),), _is_time_table, "a non-empty list of [t, P] pairs with increasing t")
    period: float = _period()


@dataclass(frozen=True)
class InletPressureFile:
    """A :class:`InletPressureTable` whose rows come from the CSV file ``file`` (relative to
    the case file's folder; to the current directory when ``--set`` gives it), read once by
    :func:`from_dict` into ``table`` (:func:`read_waveform` says what the file may hold).
    :func:`to_dict` writes it as a ``pressure_table`` of those rows, so a run's config.yaml
    does not need the file."""

    kind: Literal["pressure_file"] = "pressure_file"
    file: str = ""
    period: float = _period()
    table: tuple[tuple[float, ...], ...] = ()  # filled by from_dict, not a YAML key


@dataclass(frozen=True)
class ParabolicInflow:
    """Velocity inflow u = 1.5 Ū 4 s (H − s) / H² along the inward normal (s the distance along
    the inlet of width H), ramped by (1 − cos(π t / ramp_time)) / 2 for t < ramp_time
    (Turek–Hron: ramp_time 2 s; 0 = no ramp). Defaults: Turek–Hron CFD1/FSI1."""

    kind: Literal["parabolic_velocity"] = "parabolic_velocity"
    mean_velocity: float = positive(0.2, " (m/s)")
    ramp_time: float = non_negative(2.0, " (s)")


Inlet = Union[InletPulse, InletPressure, InletPressureTable, InletPressureFile,
              ParabolicInflow]


@dataclass(frozen=True)
class Outlet:
    """Traction-free outlet; ``backflow_stabilization`` β ≥ 0 scales the inflow-penalising term."""

    backflow_stabilization: float = non_negative(1.0)


@dataclass(frozen=True)
class SolverSettings:
    """Newton tolerances and the PETSc options of one sub-solver (its prefix is fixed).

    ``jacobian_reuse``: ``none`` assembles (and factorises) the Jacobian at every Newton
    iteration; ``step`` keeps the last one across the Newton and coupling iterations of a time
    step, ``run`` also across steps, while it still contracts the residual: it is re-assembled
    when ``|F(x_k)| > jacobian_reuse_rate · |F(x_{k−1})|`` (modified Newton, fsi/newton.py).
    The stopping test is unchanged, so is the converged answer (to the solver's tolerance); a
    failed solve with a reused Jacobian is repeated with fresh ones. ``step`` keeps restarts
    exact (the path of a step depends only on the state at its start)."""

    rtol: float = positive(1.0e-9)
    atol: float = positive(1.0e-10)
    max_iterations: int = at_least(25, 1)
    jacobian_reuse: Literal["none", "step", "run"] = "none"
    jacobian_reuse_rate: float = open_interval(0.3, 0.0, 1.0)
    # Names and values are checked against an allow-list (check_petsc_options) in validate().
    petsc_options: dict[str, Union[str, int, float]] = field(
        default_factory=lambda: {
            "ksp_type": "preonly",
            "pc_type": "lu",
            "pc_factor_mat_solver_type": "mumps",
        }
    )


@dataclass(frozen=True)
class Fluid:
    """Blood (MODEL.md §2) and its open boundaries (docs/boundary-conditions.md compares the
    options; the defaults are the verified choice of the study's cases).

    ``open_boundary`` is the form of the inlet/outlet traction conditions: ``do_nothing``
    μ ∇u n − p n = −P n (Heywood, Rannacher & Turek 1996), exact for fully developed flow;
    ``stress`` σ n = −P n (σ the Cauchy stress), whose tangential part forbids fully developed
    flow. ``normal_flow``: the velocity on a traction inlet is normal to it (u·t = 0, strongly;
    the "normal flow" pressure inlet of commercial CFD codes) and only the normal traction is
    prescribed there, so the inlet keeps its static pressure P. ``inflow_stabilization`` β ≥ 0
    adds −β/2 ρ min(u·n, 0) u to a traction inlet's σ n: at an inlet, where all the flow is
    inflow, that lowers the pressure by β ρ (u·n)²/2, i.e. it makes the static-pressure inlet
    nearly a total-pressure one (0, the default, keeps the study's static pressure).
    ``supg``: streamline-upwind/Petrov–Galerkin stabilization of the momentum equation
    (Brooks & Hughes 1982; τ of Tezduyar & Osawa 2000), consistent: it adds a multiple of the
    strong residual, so an exact discrete solution (Poiseuille flow) is unchanged; for flows
    whose cell Reynolds number at the inlet is too high for the Galerkin form."""

    density: float = positive(1060.0, " (kg/m^3)")
    rheology: Rheology = field(default_factory=Newtonian)
    inlet: Inlet = field(default_factory=InletPulse)
    outlet: Outlet = field(default_factory=Outlet)
    open_boundary: Literal["stress", "do_nothing"] = "do_nothing"
    normal_flow: bool = True
    supg: bool = False
    inflow_stabilization: float = non_negative(0.0)
    quadrature_degree: int = quadrature(4)
    solver: SolverSettings = field(default_factory=SolverSettings)


# --------------------------------------------------------------------------------------------
# Structure


@dataclass(frozen=True)
class Material:
    """Hyperelastic material of one structure region (MODEL.md §3; fsi/materials.py): the
    study's St. Venant–Kirchhoff ``svk`` or a compressible ``neo_hookean``, plane strain.
    ``viscous_relaxation_time`` τ (s) adds the Kelvin–Voigt viscous stress
    ``S_v = τ (λ tr Ė I + 2μ Ė)`` (docs/wall-damping.md): every small-amplitude mode of
    angular frequency ω gets the damping ratio ζ = ωτ/2; 0 (the default) is purely elastic."""

    law: Literal["svk", "neo_hookean"] = "svk"
    density: float = positive(1200.0, " (kg/m^3)")
    young_modulus: float = positive(1.6e6, " (Pa)")
    poisson_ratio: float = open_interval(0.45, -1.0, 0.5)
    viscous_relaxation_time: float = non_negative(0.0, " (s)")


@dataclass(frozen=True)
class WallMaterial(Material):
    """The vessel wall's defaults (E = 4 MPa); keys not given keep these, not the plaque's."""

    young_modulus: float = positive(4.0e6, " (Pa)")


@dataclass(frozen=True)
class FlagMaterial(Material):
    """The Turek–Hron flag's defaults (CSM1/FSI1: ρ 1000, μs 0.5 MPa → E 1.4 MPa, ν 0.4)."""

    density: float = positive(1000.0, " (kg/m^3)")
    young_modulus: float = positive(1.4e6, " (Pa)")
    poisson_ratio: float = open_interval(0.4, -1.0, 0.5)


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Chung–Hulbert generalized-α with high-frequency spectral radius ρ∞ (1: no dissipation,
    0: asymptotic annihilation). The study does not state its scheme; a dissipative default
    damps the structure's unresolved modes (their periods are far below the 5 ms step)."""

    scheme: Literal["generalized_alpha"] = "generalized_alpha"
    spectral_radius: float = _check(0.5, lambda v: 0 <= v <= 1, "a number in [0, 1]")


@dataclass(frozen=True)
class Newmark:
    """The trapezoidal rule (β = 1/4, γ = 1/2): no numerical dissipation, energy-conserving."""

    scheme: Literal["newmark"] = "newmark"


@dataclass(frozen=True)
class QuasiStatic:
    """No inertia: the structure is in equilibrium with its loads at every step."""

    scheme: Literal["quasi_static"] = "quasi_static"


StructuralTimeIntegration = Union[GeneralizedAlpha, Newmark, QuasiStatic]


@dataclass(frozen=True)
class TissueSupport:
    """The surrounding tissue as a spring–dashpot on the wall's exterior ΓN (Moireau et al.
    2012; docs/wall-damping.md), normal direction only: ``P N = −(k_s η·N + c_s η̇·N) N``
    per unit reference length, with ``stiffness`` k_s (Pa/m) and ``damping`` c_s (Pa·s/m).
    0 and 0 (the defaults): a traction-free exterior. Acts where ΓN is free (``moving_wall``;
    inert in ``fixed_wall``, where the wall is held); the Turek–Hron flag has no ΓN and
    ignores it (with a warning)."""

    stiffness: float = non_negative(0.0, " (Pa/m)")
    damping: float = non_negative(0.0, " (Pa s/m)")


@dataclass(frozen=True)
class Structure:
    """``fixed_wall``: vessel wall held, plaque deforms; ``moving_wall``: wall and plaque deform
    (clamped at the wall ends; the Turek–Hron flag at its joint with the cylinder); ``rigid``: no
    structure solve (fluid-only runs). ``flag`` is the Turek–Hron flag's material (CSM1/FSI1
    values by default); ``support`` the surrounding tissue on the stenosis wall's exterior ΓN
    (:class:`TissueSupport`; ignored by the Turek–Hron flag, which has no ΓN);
    ``body_force`` a force per unit mass on the structure (gravity, m/s²);
    ``degree`` the Lagrange degree of the displacement (P1 locks in bending).
    ``interface_load``: ``fluid`` couples the structure to the blood; ``inlet_pressure`` solves
    the structure alone under the follower pressure P(t) of ``fluid.inlet`` on the interface
    (no fluid solve); ``none`` solves it alone under ``body_force`` only (Turek–Hron CSM)."""

    mode: Literal["fixed_wall", "moving_wall", "rigid"] = "fixed_wall"
    interface_load: Literal["fluid", "inlet_pressure", "none"] = "fluid"
    wall: WallMaterial = field(default_factory=WallMaterial)
    cap: Material = field(default_factory=Material)
    lipid: Material = field(default_factory=Material)
    flag: FlagMaterial = field(default_factory=FlagMaterial)
    support: TissueSupport = field(default_factory=TissueSupport)
    body_force: tuple[float, ...] = _check(
        (0.0, 0.0), lambda v: len(v) == 2, "a list of two numbers [gx, gy] (m/s^2)")
    time_integration: StructuralTimeIntegration = field(default_factory=GeneralizedAlpha)
    degree: int = _check(2, lambda v: 1 <= v <= 3, "an integer in [1, 3]")
    quadrature_degree: int = quadrature(4)
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
    """The step schedule; the default is the study's: 5 ms to 0.4 s, then 10 ms to 0.8 s.

    ``scheme``: the fluid's time scheme. ``steady`` drops ∂u/∂t and the mesh velocity: every
    step solves the steady equations with the boundary data at its time (a continuation through
    an inflow ramp); with a ``quasi_static`` structure a coupled step is a steady FSI solve.

    ``retries``: how often a step whose solve fails is taken again as two steps of half its
    size, from the state before it (each half may be halved again while retries remain: up to
    2^retries substeps); the metrics row is the scheduled step's. 0: a failed step ends the run.

    ``max_steps``: validation refuses a schedule of more steps to ``end`` (:func:`count_steps`),
    so a mistyped ``dt`` fails at once instead of running for ever.
    """

    end: float = positive(0.8, " (s)")
    scheme: Literal["backward_euler", "bdf2", "steady"] = "bdf2"
    schedule: tuple[TimeSegment, ...] = (TimeSegment(0.4, 5.0e-3), TimeSegment(0.8, 1.0e-2))
    retries: int = _check(0, lambda v: 0 <= v <= 8, "an integer in [0, 8]")
    max_steps: int = at_least(1_000_000, 1)


@dataclass(frozen=True)
class Coupling:
    """Dirichlet–Neumann iterations per step (MODEL.md §5; fsi/coupling.py).

    ``initial_relaxation``: ω of constant relaxation, Aitken's first ω and IQN-ILS's relaxed
    first iteration; ``max_relaxation``: Aitken's cap |ω| <= ω_max; ``iqn_reuse``: time steps
    whose secant columns IQN-ILS reuses; ``iqn_filter``: its QR filter threshold (relative);
    ``predictor``: extrapolation of the interface displacement from previous steps.
    """

    acceleration: Literal["constant", "aitken", "iqn-ils"] = "aitken"
    tolerance: float = positive(1.0e-6)
    max_iterations: int = at_least(50, 1)
    initial_relaxation: float = _check(0.5, lambda v: 0 < v <= 1, "a number in (0, 1]")
    max_relaxation: float = positive(1.0)
    iqn_reuse: int = at_least(4, 0)
    iqn_filter: float = positive(1.0e-2)  # 1e-8 kept stale columns: IQN diverged on the stenosis
    predictor: Literal["constant", "linear", "quadratic"] = "linear"


@dataclass(frozen=True)
class MeshMotion:
    """ALE extension of the interface displacement into the fluid (MODEL.md §5;
    fsi/mesh_motion.py): ``harmonic`` −∇·(k ∇d) = 0 or ``elastic`` −∇·(k σ(d)) = 0 with
    σ = 2 ε + λ' tr(ε) I, λ' = 2ν/(1 − 2ν) from ``poisson_ratio``. Stiffening k (per cell):
    ``none`` k = 1; ``jacobian`` k = (J_max/J)^e with J the reference cell area (small cells
    stiffer); ``distance`` k = (δ_max/δ)^e with δ the centroid's distance to the moving boundary;
    e = ``stiffening_exponent``. ``min_jacobian_ratio``: the quality guard stops when a cell's
    area falls below this fraction of its reference area (or the cell inverts).
    ``petsc_options``: the linear solver's options (prefix ``mesh_``)."""

    method: Literal["harmonic", "elastic"] = "harmonic"
    stiffening: Literal["none", "jacobian", "distance"] = "jacobian"
    stiffening_exponent: float = non_negative(1.0)
    poisson_ratio: float = open_interval(0.3, -1.0, 0.5)
    min_jacobian_ratio: float = open_interval(0.05, 0.0, 1.0)
    petsc_options: dict[str, Union[str, int, float]] = field(
        default_factory=lambda: {
            "ksp_type": "preonly",
            "pc_type": "lu",
            "pc_factor_mat_solver_type": "mumps",
        }
    )


@dataclass(frozen=True)
class Output:
    # XDMF only: Debian 12's dolfinx has no ADIOS2 (no VTX), and 0.9's VTX writer takes one
    # element per file, where a run writes P1 and per-cell fields side by side.
    fields: Literal["xdmf"] = "xdmf"
    fields_every: int = at_least(1, 1)
    checkpoint_every: int = at_least(10, 1)
    report_times: tuple[float, ...] = _check((0.01, 0.02, 0.05, 0.1, 0.8),
                                             lambda v: all(t >= 0 for t in v),
                                             "a list of times >= 0 (s)")


@dataclass(frozen=True)
class Case:
    name: str = "case"
    geometry: Union[StenosisGeometry, ChannelGeometry, TurekHronGeometry] = field(
        default_factory=StenosisGeometry)
    mesh: MeshSettings = field(default_factory=MeshSettings)
    fluid: Fluid = field(default_factory=Fluid)
    structure: Structure = field(default_factory=Structure)
    time: Time = field(default_factory=Time)
    coupling: Coupling = field(default_factory=Coupling)
    mesh_motion: MeshMotion = field(default_factory=MeshMotion)
    output: Output = field(default_factory=Output)


# --------------------------------------------------------------------------------------------
# Loading


def load(path: str | Path, overrides: typing.Sequence[str] = ()) -> Case:
    """Read a case from YAML, apply ``key.path=value`` overrides, build and validate it.

    Every failure is a :class:`ConfigError` naming the file (or ``--set``) and the key: an
    unreadable file, one larger than :data:`MAX_FILE_BYTES` or not UTF-8 text, invalid or too
    deeply nested YAML, a repeated key, and whatever :func:`from_dict` refuses.
    """
    path = Path(path)
    source = str(path)
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)  # bounded: /dev/zero is refused, not read for ever
    except OSError as e:
        raise ConfigError(source, "<file>", "a readable YAML file", e.strerror) from None
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(source, "", reason=f"larger than {MAX_FILE_BYTES} bytes: not a case "
                                              "file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(source, "", reason=f"not UTF-8 text (byte 0x{raw[e.start]:02x} at "
                                              f"offset {e.start}): not a case file") from None
    try:
        data = parse_yaml(text, source)
    except YAMLTooDeep as e:
        raise ConfigError(source, "", reason=str(e)) from None
    except yaml.YAMLError as e:
        raise ConfigError(source, "<file>", f"valid YAML ({e})".replace("\n", " ")) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(source, "<top level>", "a mapping of sections", type(data).__name__)
    overridden = apply_overrides(data, overrides)
    return from_dict(data, source, overridden)


def apply_overrides(data: dict, overrides: typing.Sequence[str]) -> set[str]:
    """Set ``key.path=value`` (value parsed as YAML) in ``data``; return the keys set and the
    sections the overrides created (a section not in ``data`` comes from the command line)."""
    keys = set()
    for item in overrides:
        key, sep, text = item.partition("=")
        if not sep or not key or any(not part for part in key.split(".")):
            raise ConfigError("--set", _shorten(item), "key.path=value")
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


def from_dict(data: dict, source: str = "<dict>", overridden: set[str] | None = None) -> Case:
    """Build and validate a :class:`Case` from a plain dict (as read from YAML).

    ``overridden``: the keys :func:`apply_overrides` set (and the sections it created); an
    error at one of them, below one (``time.schedule[0].dt`` below ``time.schedule``) or about
    a whole section one changed (``mesh``'s cell count after ``--set mesh.size=...``) names
    ``--set`` instead of ``source``."""
    overridden = overridden or set()
    try:
        case = _build(Case, data, "")
        case = _read_inlet_file(case, source, overridden)
        validate(case)
    except ConfigError as e:
        from_command_line = any(e.key == k or e.key.startswith((k + ".", k + "["))
                                or k.startswith(e.key + ".") for k in overridden)
        raise e.from_source("--set" if from_command_line else source) from None
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
    """Convert a YAML value to type ``tp`` strictly (no str→bool, no bool→number, no float→int,
    no inf or nan for any number)."""
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError("", key or "<top level>", "a mapping", value)
        fields = {f.name: f for f in dataclasses.fields(tp)}
        unknown = sorted(set(value) - set(fields), key=str)
        if unknown:
            k = f"{key}.{unknown[0]}" if key else str(unknown[0])
            raise ConfigError("", k, "one of the keys " + ", ".join(fields), "unknown key")
        kwargs = {}
        hints = typing.get_type_hints(tp)
        for name, f in fields.items():
            if name not in value:
                continue
            sub = f"{key}.{name}" if key else name
            expected = f.metadata.get("expected")
            if hints[name] is float and expected is not None and not _finite(value[name]):
                # "a positive number (s)" -> "a finite positive number (s)"
                raise ConfigError("", sub, "a finite " + expected.removeprefix("a "), value[name])
            v = _build(hints[name], value[name], sub)
            if "check" in f.metadata:
                try:
                    allowed = f.metadata["check"](v)
                except ValueError as e:
                    raise ConfigError("", sub, f"{expected} ({getattr(e, 'reason', e)})",
                                      v) from None
                if not allowed:
                    raise ConfigError("", sub, expected, v)
            kwargs[name] = v
        return tp(**kwargs)
    if origin in (Union, types.UnionType):
        options = typing.get_args(tp)
        if all(dataclasses.is_dataclass(o) for o in options):
            return _build_tagged(options, value, key)
        if float in options and not _finite(value):
            raise ConfigError("", key, "a finite number", value)
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
        try:
            number = float(value)
        except OverflowError:  # an integer of hundreds of digits
            number = math.inf
        if not math.isfinite(number):
            raise ConfigError("", key, "a finite number", value)
        return number
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
    elif isinstance(g, TurekHronGeometry):
        # Any structure mode: 'rigid' is the CFD benchmark, the others make the flag elastic.
        _validate_turek_hron(g)
    elif case.structure.mode != "rigid":
        raise ConfigError("", "structure.mode", f"'rigid' for geometry.kind '{g.kind}'"
                          " (it has no structure)", case.structure.mode)
    if case.structure.interface_load != "fluid":
        if case.structure.mode == "rigid":
            raise ConfigError("", "structure.interface_load", "'fluid' when structure.mode is "
                              "'rigid' (there is no structure to load)",
                              case.structure.interface_load)
        if (case.structure.interface_load == "inlet_pressure"
                and isinstance(case.fluid.inlet, ParabolicInflow)):
            raise ConfigError("", "structure.interface_load", "'fluid' or 'none' with a "
                              "velocity inlet ('inlet_pressure' needs a traction inlet)",
                              case.structure.interface_load)
    _validate_cell_count(case)  # before the size order: mesh.size 1e-6 gets the estimate
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
    count = count_steps(case.time)
    if count > case.time.max_steps:
        raise_limit = (f"raise the limit (--set time.max_steps={int(count)}) if you mean it"
                       if math.isfinite(count) else "no limit can be that high")
        raise ConfigError("", "time.schedule", reason=(
            f"{_count(count)} steps to time.end = {case.time.end:g} s, more than "
            f"time.max_steps = {case.time.max_steps:,}: use larger dt, or {raise_limit}"))

    if (case.time.scheme == "steady" and case.structure.mode != "rigid"
            and case.structure.time_integration.scheme != "quasi_static"):
        raise ConfigError("", "structure.time_integration.scheme", "'quasi_static' when "
                          "time.scheme is 'steady' (a steady fluid cannot load a structure "
                          "with inertia)", case.structure.time_integration.scheme)

    if case.coupling.max_relaxation < case.coupling.initial_relaxation:
        raise ConfigError("", "coupling.max_relaxation", "at least coupling.initial_relaxation ="
                          f" {case.coupling.initial_relaxation}", case.coupling.max_relaxation)

    # Sub-solvers must be well below the coupling tolerance or the coupling stalls near it.
    for name in ("fluid", "structure"):
        rtol = getattr(case, name).solver.rtol
        if rtol > case.coupling.tolerance / 10:
            raise ConfigError("", f"{name}.solver.rtol",
                              f"at most coupling.tolerance / 10 = {case.coupling.tolerance / 10:g}",
                              rtol)

    check_petsc_options(case.fluid.solver.petsc_options, "fluid.solver.petsc_options")
    check_petsc_options(case.structure.solver.petsc_options, "structure.solver.petsc_options")
    check_petsc_options(case.mesh_motion.petsc_options, "mesh_motion.petsc_options")
    _validate_inlet(case)  # last: it walks the schedule, now known to be of bounded length


def _count(n: float) -> str:
    """A step or cell count for a message: ``1,234,567``, ``8e+12`` if huge, ``over 1e308`` if
    it overflowed."""
    if not math.isfinite(n):
        return "over 1e308"
    return f"{n:.3g}" if n >= 1e12 else f"{int(n):,}"


def count_steps(time: Time) -> float:
    """The number of steps :func:`fsi.timestepping.steps` takes from t = 0 to ``time.end``,
    counted per segment arithmetically (a schedule of 10¹² steps costs no more than one of 10;
    inf for a dt so small that the count overflows). Each segment's steps end on its ``until``
    (or ``end``), a remainder below 1e-9 dt merged into the last step, as ``steps`` does."""
    t, n = 0.0, 0
    for segment in time.schedule:
        stop = min(segment.until, time.end)
        if stop - t > 1e-9 * segment.dt:
            segment_steps = (stop - t) / segment.dt
            n += math.ceil(segment_steps - 1e-9) if segment_steps < 2.0**52 else segment_steps
            t = stop
        if time.end <= segment.until:
            break
    return n


TRIANGLE_AREA = math.sqrt(3) / 4
"""Area of an equilateral triangle of side 1: a gmsh triangle of size h covers about
``TRIANGLE_AREA · h²``."""


def estimated_cells(case: Case) -> float:
    """About how many triangles :func:`fsi.mesh.build` makes for ``case``, from the geometry
    alone (no gmsh): area / (TRIANGLE_AREA h²), × 4 per uniform refinement of ``mesh.level``.

    The size field h is modelled per geometry: ``size`` everywhere in a channel; in the
    stenosis ``local_size`` over the box under each plaque (stenosis_length × plaque height)
    and ``size`` elsewhere; in Turek–Hron ``local_size + grading · d`` up to ``size`` at the
    distance d from the cylinder and the flag (the builder's Threshold field, integrated over
    bands around the obstacle). Within a factor 1.5 of gmsh's count on the shipped cases (its
    tests check a factor 3); meant for refusing absurd sizes, not for planning.
    """
    g, m = case.geometry, case.mesh
    size, local = m.size, min(m.local_size, m.size)
    if isinstance(g, StenosisGeometry):
        total = stenosis_geometry.analytic_areas(g)["total"]
        fine_area = len(g.plaque_sides) * stenosis_geometry.plaque_height(g) * g.stenosis_length
        per_size2 = (total - fine_area) / size / size + fine_area / local / local
    elif isinstance(g, TurekHronGeometry):
        per_size2 = _turek_hron_cells_area(g, size, local)
    else:
        per_size2 = g.length * g.height / size / size
    return per_size2 / TRIANGLE_AREA * 4.0**m.refinements


def _turek_hron_cells_area(g: TurekHronGeometry, size: float, local: float) -> float:
    """∫ dA / h² over the Turek–Hron channel with h(d) = min(size, local + k d), k the
    builder's grading and d the distance to the obstacle (perimeter P, convex): the band
    d < D = (size − local)/k, whose level line at d has length P + 2π d, gives
    ``∫₀^D (P + 2π d) / (local + k d)² dd``; the rest of the channel is at ``size``."""
    k = turek_hron_geometry.GRADING
    r, t = g.cylinder_radius, g.flag_thickness
    x_joint = g.cylinder_centre[0] + math.sqrt(r * r - t * t / 4)
    perimeter = 2 * math.pi * r + 2 * (turek_hron_geometry.tip_x(g) - x_joint) + t
    band = (size - local) / k
    near = (perimeter / k * (1 / local - 1 / size)
            + 2 * math.pi / k**2 * (math.log(size / local) + local / size - 1))
    total = turek_hron_geometry.analytic_areas(g)["total"]
    rest = max(total - perimeter * band - math.pi * band**2, 0.0)
    return near + rest / size / size


BYTES_PER_CELL = 18e3
"""Memory per triangle of a coupled run, measured: the fine stenosis (51k triangles) ~0.9 GB."""


def _validate_cell_count(case: Case) -> None:
    """Refuse a mesh whose :func:`estimated_cells` exceeds ``mesh.max_cells``, before gmsh."""
    cells = estimated_cells(case)
    if cells > case.mesh.max_cells:
        m = case.mesh
        gigabytes = cells * BYTES_PER_CELL / 1e9
        memory = (f"{gigabytes:.2g} GB" if gigabytes < 10 else f"{gigabytes:,.0f} GB"
                  if gigabytes < 1e9 else "too much")
        raise ConfigError("", "mesh", reason=(
            f"{_count(cells)} triangles estimated (mesh.size = {m.size:g} m, mesh.local_size = "
            f"{m.local_size:g} m, mesh.level = {m.level}), more than mesh.max_cells = "
            f"{m.max_cells:,} (a coupled run needs ~{BYTES_PER_CELL / 1e3:.0f} kB per triangle:"
            f" {memory}): use larger sizes or a coarser level, or raise mesh.max_cells if you "
            "mean it"))


def _validate_inlet(case: Case) -> None:
    """Evaluate an inlet formula at t = 0 and at every step time of the schedule: one that
    fails (division by zero, log(0), overflow, ...) is refused now, not mid-run."""
    inlet = case.fluid.inlet
    if isinstance(inlet, (InletPressureTable, InletPressureFile)):
        _validate_period(inlet)
    if not isinstance(inlet, InletPressure):
        return  # the pulse is closed-form; a table holds finite numbers and interpolates
    pressure = time_function(inlet.formula)
    try:
        pressure(0.0)
        for step in steps(case.time):
            pressure(step.t)
    except FormulaError as e:
        raise ConfigError("", "fluid.inlet.formula",
                          reason=f"evaluation fails at t = {e.t:.6g} s ({e.reason})") from None


# --------------------------------------------------------------------------------------------
# PETSc options: an allow-list, since PETSc options can run code and write files

# Sub-solver prefixes inside one solver's options: the blocks of block Jacobi / ASM (sub_),
# the redundant PC, multigrid levels, fieldsplit blocks and a smoother's eigenvalue estimator.
_PETSC_SUBSOLVER = (r"(?:(?:sub|redundant|mg_coarse|mg_levels(?:_[0-9]+)?|fieldsplit_[a-z0-9]+"
                    r"|esteig)_)*")

_PETSC_OPTIONS = (
    # Krylov method: type, tolerances, iteration limits, restart lengths
    r"ksp_(?:type|rtol|atol|divtol|max_it|norm_type|pc_side|initial_guess_nonzero"
    r"|error_if_not_converged|reuse_preconditioner|gmres_restart|gcr_restart"
    r"|gmres_modifiedgramschmidt|gmres_cgs_refinement_type|richardson_scale"
    r"|chebyshev_eigenvalues|chebyshev_esteig)",
    # preconditioner type; LU / ILU / Cholesky factorisations and the package that does them
    r"pc_(?:type|factor_mat_solver_type|factor_mat_ordering_type|factor_levels|factor_fill"
    r"|factor_shift_type|factor_shift_amount|factor_nonzeros_along_diagonal"
    r"|factor_pivot_in_blocks|jacobi_type|sor_omega|sor_its|sor_symmetric|asm_overlap|asm_type"
    r"|bjacobi_blocks)",
    # MUMPS (not ICNTL 1-4: output streams and print level; not 22: out-of-core files; 37, 48
    # and 58 need PETSc >= 3.20, older ones ignore them)
    r"mat_mumps_icntl_(?:6|7|8|10|11|12|13|14|23|24|25|27|28|29|35|36|37|38|48|58)",
    r"mat_mumps_cntl_[1-57]",
    r"mat_superlu_dist_(?:rowperm|colperm|equil|replacetinypivot|iterrefine)",
    # hypre BoomerAMG
    r"pc_hypre_type",
    r"pc_hypre_boomeramg_(?:strong_threshold|coarsen_type|interp_type|agg_nl|agg_num_paths"
    r"|max_iter|tol|max_levels|truncfactor|p_max|max_row_sum|cycle_type|relax_type_(?:all|down"
    r"|up|coarse)|grid_sweeps_(?:all|down|up|coarse)|relax_weight_all|outer_relax_weight_all"
    r"|nodal_coarsen|vec_interp_variant|numfunctions|measure_type|no_cf|smooth_type"
    r"|smooth_num_levels)",
    # GAMG and geometric/algebraic multigrid cycles
    r"pc_gamg_(?:type|threshold|threshold_scale|agg_nsmooths|square_graph|aggressive_coarsening"
    r"|coarse_eq_limit|process_eq_limit|reuse_interpolation|repartition"
    r"|esteig_ksp_type|esteig_ksp_max_it|use_sa_esteig|asm_use_agg"
    r"|use_parallel_coarse_grid_solver)",
    r"pc_mg_(?:levels|cycle_type|type|smoothup|smoothdown|galerkin|distinct_smoothup)",
    # fieldsplit and Schur complements
    r"pc_fieldsplit_(?:type|schur_fact_type|schur_precondition|schur_scale|detect_saddle_point"
    r"|block_size|diag_use_amat|off_diag_use_amat|[a-z0-9]+_fields)",
)
_PETSC_ALLOWED = re.compile(_PETSC_SUBSOLVER + "(?:" + "|".join(_PETSC_OPTIONS) + ")")

# Why a name is refused: patterns (searched in the lower-case name) of dangerous options.
_PETSC_REFUSED = (
    ("python", "a Python type imports and runs code the configuration names"),
    ("view", "viewers write to any file their value names (ascii:/path)"),
    ("monitor", "monitors write to any file their value names"),
    ("options", "options files and aliases read or inject other options"),
    (r"mat_mumps_icntl_[1-4]$", "MUMPS ICNTL 1-4 choose output streams and printing"),
    (r"mat_mumps_icntl_22$", "MUMPS ICNTL 22 writes out-of-core files"),
    ("print", "printing options write output"),
    ("log", "logging options write files"),
    ("dump", "dump options write files"),
    ("draw", "drawing options open windows or write files"),
)
_PETSC_TYPE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")
_HYPRE_NAMES = frozenset((
    "Jacobi", "sequential-Gauss-Seidel", "seqboundary-Gauss-Seidel", "SOR/Jacobi",
    "backward-SOR/Jacobi", "symmetric-SOR/Jacobi", "l1scaled-SOR/Jacobi",
    "Gaussian-elimination", "l1-Gauss-Seidel", "backward-l1-Gauss-Seidel", "CG", "Chebyshev",
    "FCF-Jacobi", "l1scaled-Jacobi", "CLJP", "Ruge-Stueben", "modifiedRuge-Stueben", "Falgout",
    "PMIS", "HMIS", "classical", "direct", "multipass", "multipass-wts", "ext+i", "ext+i-cc",
    "standard", "standard-wts", "FF", "FF1", "ext", "ext-mm", "ext+i-mm", "ext+e-mm"))
"""BoomerAMG's smoother, coarsening and interpolation names: fixed words of PETSc's hypre
interface, accepted although they contain ``/``, ``-`` or ``+``."""
_NUMBER = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
_PETSC_NUMBERS = re.compile(f"{_NUMBER}(?:,{_NUMBER}){{0,63}}")  # "0.01", "0,1", "0.1,1.1"


def check_petsc_options(options: dict[str, str | int | float], key: str) -> None:
    """Raise :class:`ConfigError` naming ``key.<name>`` unless every option is on the allow-list.

    A configuration sets PETSc options under its solver's prefix (``fluid_``, ``solid_``,
    ``mesh_``), and PETSc options can run code (``pc_type: python`` with
    ``pc_python_type: module.Attr``) or write any file (``ksp_view: ascii:/path``). Allowed
    names (case-insensitive, as PETSc's; optionally behind sub-solver prefixes ``sub_``,
    ``redundant_``, ``mg_levels_[N_]``, ``mg_coarse_``, ``fieldsplit_<name>_``, ``esteig_``):
    Krylov types, tolerances, iteration limits and restarts; PC types and factorisations;
    MUMPS ICNTL/CNTL tuning (not its output streams or out-of-core files), SuperLU_dist;
    hypre BoomerAMG, GAMG, multigrid and fieldsplit/Schur tuning (``_PETSC_OPTIONS``). Allowed
    values: finite numbers, numbers as text or comma-separated lists of them, and type names
    of letters, digits and ``_`` (not ``python``).
    """
    for name, value in options.items():
        sub = f"{key}.{name}"
        lower = name.lower()
        if len(name) > 100 or not re.fullmatch(r"[a-z0-9_]+", lower):
            raise ConfigError("", _shorten(sub), reason="not a PETSc option name: letters, "
                              "digits and _ only, without the leading '-' (the prefix is added)")
        for pattern, why in _PETSC_REFUSED:
            if re.search(pattern, lower):
                raise ConfigError("", sub, reason=f"refused PETSc option: {why}")
        if not _PETSC_ALLOWED.fullmatch(lower):
            raise ConfigError("", sub, reason="not an allowed PETSc option (solver and "
                              "preconditioner types, tolerances, iteration limits and tuning: "
                              "the list is in docs/configuration.md)")
        if isinstance(value, str) and value not in _HYPRE_NAMES:
            if "python" in value.lower():
                raise ConfigError("", sub, reason=f"refused value {_shorten(repr(value))}: a "
                                  "Python type imports and runs code the configuration names")
            if any(c in value for c in ":/\\~"):
                raise ConfigError("", sub, reason=f"refused value {_shorten(repr(value))}: no "
                                  "file paths or viewer specifications")
            if not (_PETSC_TYPE_NAME.fullmatch(value) or _PETSC_NUMBERS.fullmatch(value)):
                raise ConfigError("", sub, "a type name (letters, digits, _), a number or "
                                  "comma-separated numbers", value)


def _validate_turek_hron(g: TurekHronGeometry) -> None:
    """The cylinder inside the channel, the flag attached to it and ending inside the channel."""
    if len(g.cylinder_centre) != 2:
        raise ConfigError("", "geometry.cylinder_centre", "a list of two numbers [x, y] (m)",
                          list(g.cylinder_centre))
    cx, cy = g.cylinder_centre
    r = g.cylinder_radius
    if not (r < cx and r < cy < g.height - r):
        raise ConfigError("", "geometry.cylinder_radius",
                          f"a cylinder of centre {list(g.cylinder_centre)} inside the channel"
                          f" [0, {g.length}] x [0, {g.height}] m", r)
    if g.flag_thickness >= 2 * r:
        raise ConfigError("", "geometry.flag_thickness",
                          f"less than the cylinder diameter {2 * r} m", g.flag_thickness)
    if cx + r + g.flag_length >= g.length:
        raise ConfigError("", "geometry.flag_length",
                          f"a flag tip (x = centre + radius + length) before the outlet x ="
                          f" {g.length} m", g.flag_length)


def to_dict(case: Case) -> dict:
    """The resolved configuration as plain YAML-ready data (tuples as lists); a
    ``pressure_file`` inlet as the ``pressure_table`` of its rows and period, so that
    :func:`load` of the data needs no CSV file and gives the same P(t)."""

    def plain(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v

    data = plain(dataclasses.asdict(case))
    inlet = case.fluid.inlet
    if isinstance(inlet, InletPressureFile):  # self-contained: the rows, not the file
        data["fluid"]["inlet"] = plain(dataclasses.asdict(
            InletPressureTable(table=inlet.table, period=inlet.period)))
    return data


def to_yaml(case: Case) -> str:
    """The resolved configuration as YAML text (``fsi run`` writes it as DIR/config.yaml)."""
    return yaml.safe_dump(to_dict(case), sort_keys=False)


def dump(case: Case, path: str | Path) -> None:
    Path(path).write_text(to_yaml(case))


# --------------------------------------------------------------------------------------------
# Inlet waveforms from CSV files


class WaveformError(ValueError):
    """A waveform CSV file cannot be used: the message names the file and, for bad content, the
    line (``waveforms/x.csv: line 7: 'abc' is not a number``)."""


def read_waveform(path: str | Path) -> tuple[tuple[float, float], ...]:
    """The rows (t (s), P (Pa)) of the CSV file ``path``.

    Guaranteed on return: at least 2 rows, every value a finite float, t strictly increasing.
    The file: UTF-8 text (a byte-order mark allowed) of at most :data:`MAX_FILE_BYTES`; one row
    ``t, P`` per line, comma-separated; blank lines and lines starting with ``#`` are skipped;
    the first other line may be a header (no cell of it a number: ``t,P``). Raises
    :class:`WaveformError` naming the file (and the line) otherwise, ``OSError`` if the file
    cannot be read.
    """
    with Path(path).open("rb") as f:
        raw = f.read(MAX_FILE_BYTES + 1)  # bounded, as a case file
    if len(raw) > MAX_FILE_BYTES:
        raise WaveformError(f"{path}: larger than {MAX_FILE_BYTES} bytes")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise WaveformError(f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} at offset "
                            f"{e.start})") from None
    rows: list[tuple[float, float]] = []
    header_allowed = True
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        cells = [cell.strip() for cell in line.split(",")]
        first, header_allowed = header_allowed, False
        values = [_number(cell) for cell in cells]
        if first and all(value is None for value in values):
            continue  # the header
        where = f"{path}: line {number}"
        if len(cells) != 2:
            raise WaveformError(f"{where}: expected 2 columns t, P, got {len(cells)}")
        for cell, value in zip(cells, values):
            if value is None:
                raise WaveformError(f"{where}: {_shorten(repr(cell), 40)} is not a number")
        t, pressure = values
        for name, value in (("t", t), ("P", pressure)):
            if not math.isfinite(value):
                raise WaveformError(f"{where}: {name} = {value} is not a finite number")
        if rows and t <= rows[-1][0]:
            raise WaveformError(f"{where}: t = {t:g} is not after the previous row's t = "
                                f"{rows[-1][0]:g}")
        rows.append((t, pressure))
    if len(rows) < 2:
        raise WaveformError(f"{path}: {len(rows)} row{'s' if len(rows) != 1 else ''} of t, P; "
                            "at least 2 are needed")
    return tuple(rows)


def _number(cell: str) -> float | None:
    """The float ``cell`` spells, or None (``float`` also takes inf and nan: checked after)."""
    try:
        return float(cell)
    except ValueError:
        return None


def _read_inlet_file(case: Case, source: str, overridden: set[str]) -> Case:
    """``case`` with a ``pressure_file`` inlet's rows read into its ``table`` (other inlets
    unchanged). ``file`` is relative to the folder of ``source`` (the case file), or to the
    current directory when ``--set`` gave it (or ``source`` is not a file: ``<dict>``); the
    path kept in the case is the one opened."""
    inlet = case.fluid.inlet
    if not isinstance(inlet, InletPressureFile):
        return case
    if inlet.table:
        raise ConfigError("", "fluid.inlet.table", reason="not a key of kind 'pressure_file' "
                          "(its rows come from fluid.inlet.file; use kind 'pressure_table' to "
                          "give them inline)")
    if not inlet.file:
        raise ConfigError("", "fluid.inlet.file", "the name of a CSV file of rows t, P "
                          "(relative to the case file's folder)")
    from_command_line = bool({"fluid", "fluid.inlet", "fluid.inlet.file"} & overridden)
    path = Path(inlet.file)
    if not path.is_absolute() and not from_command_line and source not in ("<dict>", "--set"):
        path = Path(source).parent / path
    try:
        rows = read_waveform(path)
    except OSError as e:
        raise ConfigError("", "fluid.inlet.file", reason=f"cannot read {path} "
                          f"({e.strerror or type(e).__name__})") from None
    except WaveformError as e:
        raise ConfigError("", "fluid.inlet.file", reason=str(e)) from None
    inlet = dataclasses.replace(inlet, file=str(path), table=rows)
    return dataclasses.replace(case, fluid=dataclasses.replace(case.fluid, inlet=inlet))


def _validate_period(inlet: InletPressureTable | InletPressureFile) -> None:
    """A periodic table must cover one period: first t <= 0 and last t >= period."""
    period = inlet.period
    first, last = inlet.table[0][0], inlet.table[-1][0]
    if period > 0 and not (first <= 0 <= period <= last):
        rows = (f"the rows of {inlet.file}" if isinstance(inlet, InletPressureFile)
                else "fluid.inlet.table")
        raise ConfigError("", "fluid.inlet.period", reason=(
            f"{rows} cover t in [{first:g}, {last:g}] s, not the whole period [0, {period:g}] s "
            "(the first t must be <= 0 and the last >= period)"))
