"""Time-dependent boundary data: the inlet formula language and waveform CSV files.

:func:`time_function` turns a formula in ``t`` (a restricted arithmetic language, checked
before it runs) into a function of time that returns a finite float or raises
:class:`FormulaError`; :func:`read_waveform` reads rows (t, P) from a CSV file or raises
:class:`WaveformError` naming the file and line.
"""

from __future__ import annotations

import math
import re
import stat
import typing
from pathlib import Path

import numpy as np

from fsi.config.reader import MAX_FILE_BYTES, shorten

FORMULA_NAMES = ("sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "abs", "min", "max")

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
        super().__init__(f"formula {shorten(repr(formula), 60)}{at}: {reason}")


LONG_CHAIN = 16
"""Binary operations in a row through their left operands (``a + b - c * d``: a flat sum or
product is one, as Python parses it) longer than this are evaluated as a loop
(:func:`_flatten_chains`): a Fourier series of 100 terms is 100 levels deep as a tree, which
Python 3.11 compiles only to about 1,000."""


def _spine(node) -> tuple[object, list]:
    """The left spine of the binary operation ``node``: its innermost left operand and the
    (operator, right operand) pairs in evaluation order (``a + b - c`` → a, [(+, b), (−, c)])."""
    import ast

    pairs = []
    while isinstance(node, ast.BinOp):
        pairs.append((node.op, node.right))
        node = node.left
    return node, pairs[::-1]


def _depth(tree) -> int:
    """The depth of a syntax tree as it is compiled (without recursion: the tree may be deep):
    a chain of more than :data:`LONG_CHAIN` binary operations counts as one level, since
    :func:`_flatten_chains` makes it one call."""
    import ast

    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if isinstance(node, ast.BinOp):
            base, pairs = _spine(node)
            if len(pairs) > LONG_CHAIN:
                stack.extend((child, depth + 1) for child in (base, *(r for _, r in pairs)))
                continue
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return deepest


def _flatten_chains(tree):
    """``tree`` with every chain of more than :data:`LONG_CHAIN` binary operations replaced by
    a call ``_chain(a, op₁, b₁, op₂, b₂, ...)`` that applies them in a loop, left to right as
    Python does: the same operations in the same order, so the same float result, but one
    level deep for the compiler (without recursion: the tree may be deep)."""
    import ast

    def flattened(node):
        if not isinstance(node, ast.BinOp):
            return node
        base, pairs = _spine(node)
        if len(pairs) <= LONG_CHAIN:
            return node
        args = [base]
        for op, right in pairs:
            args += [ast.Constant(_operator_index(op)), right]
        return ast.Call(func=ast.Name(id="_chain", ctx=ast.Load()), args=args, keywords=[])

    tree.body = flattened(tree.body)
    stack = [tree.body]
    while stack:
        node = stack.pop()
        for name, value in ast.iter_fields(node):
            if isinstance(value, list):
                value[:] = [flattened(v) if isinstance(v, ast.expr) else v for v in value]
                stack.extend(v for v in value if isinstance(v, ast.AST))
            elif isinstance(value, ast.expr):
                setattr(node, name, flattened(value))
                stack.append(getattr(node, name))
    return ast.fix_missing_locations(tree)


def _operator_functions() -> dict:
    import ast
    import operator

    return {
        ast.Add: operator.add,
        ast.Sub: operator.sub,
        ast.Mult: operator.mul,
        ast.Div: operator.truediv,
        ast.Pow: operator.pow,
        ast.Mod: operator.mod,
    }


def _operator_index(op) -> int:
    return list(_operator_functions()).index(type(op))


def _chain(first, *rest):
    """``first`` op₁ b₁ op₂ b₂ ... evaluated left to right (``rest``: operator index, operand)."""
    functions = list(_operator_functions().values())
    value = first
    for i in range(0, len(rest), 2):
        value = functions[rest[i]](value, rest[i + 1])
    return value


def time_function(formula: str) -> typing.Callable[[float], float]:
    """``formula``, an arithmetic expression in the time ``t`` (s), as a function of t.

    Allowed: numbers, ``t``, ``pi``, ``e``, ``+ - * / ** %``, parentheses, comparisons (true = 1,
    e.g. ``600*(1 - cos(2*pi*t/0.005))*(t <= 0.005)``) and the functions sin, cos, tan, exp, log,
    sqrt, tanh, abs, min, max, in at most :data:`MAX_FORMULA_LENGTH` characters. Raises
    :class:`FormulaError` (a ValueError) for anything else (names, attributes, strings, nesting
    too deep to compile). The function returned returns a finite float or raises
    :class:`FormulaError` naming the formula and t; it raises nothing else.
    """
    tree = _parse_formula(formula)
    _check_formula_nodes(formula, tree)
    try:
        code = compile(_flatten_chains(tree), "<formula>", "eval")
    except (ValueError, RecursionError, MemoryError) as e:
        raise FormulaError(formula, f"cannot be compiled: {_nesting(e)}") from None
    return _formula_value(formula, code)


def _parse_formula(formula: str):
    """The syntax tree of ``formula`` (an expression at most :data:`MAX_FORMULA_LENGTH` long and
    :data:`MAX_FORMULA_DEPTH` deep), or :class:`FormulaError`."""
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
    return tree


def _check_formula_nodes(formula: str, tree) -> None:
    """Raise :class:`FormulaError` at the first node of ``tree`` outside the formula language;
    turn every number constant into a float (in place) on the way."""
    import ast

    allowed = (
        ast.Expression,
        ast.BinOp,
        ast.UnaryOp,
        ast.Compare,
        ast.Call,
        ast.Name,
        ast.Load,
        ast.Constant,
        ast.operator,
        ast.unaryop,
        ast.cmpop,
    )
    for node in ast.walk(tree):
        if not isinstance(node, allowed) or isinstance(
            node,
            (
                ast.MatMult,
                ast.BitAnd,
                ast.BitOr,
                ast.BitXor,
                ast.LShift,
                ast.RShift,
                ast.FloorDiv,
                ast.Invert,
                ast.Not,
                ast.Is,
                ast.IsNot,
                ast.In,
                ast.NotIn,
            ),
        ):
            raise FormulaError(formula, f"{type(node).__name__} is not allowed")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise FormulaError(formula, f"{shorten(repr(node.value), 40)} is not a number")
            try:
                node.value = float(node.value)  # float powers overflow instead of running forever
            except OverflowError:
                raise FormulaError(formula, "a number too large for a float") from None
        if isinstance(node, ast.Name) and node.id not in ("t", "pi", "e", *FORMULA_NAMES):
            raise FormulaError(formula, f"unknown name {node.id!r}")
        if isinstance(node, ast.Call) and (
            node.keywords
            or not isinstance(node.func, ast.Name)
            or node.func.id not in FORMULA_NAMES
        ):
            raise FormulaError(formula, "only calls of " + ", ".join(FORMULA_NAMES))


def _formula_value(formula: str, code) -> typing.Callable[[float], float]:
    """The function of t evaluating the checked, compiled ``code`` of ``formula``: it returns a
    finite float or raises :class:`FormulaError` naming the formula and t."""
    names = {"__builtins__": {}, "pi": math.pi, "e": math.e, "abs": abs, "min": min, "max": max}
    names["_chain"] = _chain  # long chains of operations (not a name formulas may use)
    names.update({f: getattr(math, f) for f in FORMULA_NAMES if hasattr(math, f)})

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


def table_function(
    rows: typing.Sequence[typing.Sequence[float]], period: float = 0.0
) -> typing.Callable[[float], float]:
    """The function of t of the rows [t, y] (t increasing): linear between rows; with
    ``period`` T > 0 of t mod T, else constant beyond the first and last row."""
    times, values = np.array(rows, dtype=float).T
    if period > 0:
        return lambda t: float(np.interp(t % period, times, values))
    return lambda t: float(np.interp(t, times, values))


def periodic(function: typing.Callable[[float], float], period: float):
    """``function`` of t mod ``period`` (s), or ``function`` itself for period 0."""
    return (lambda t: function(t % period)) if period > 0 else function


class WaveformError(ValueError):
    """A waveform CSV file cannot be used: the message names the file and, for bad content, the
    line (``waveforms/x.csv: line 7: 'abc' is not a number``)."""


def read_waveform(
    path: str | Path, quantity: str = "P", *, axisymmetric: bool = False
) -> tuple[tuple[float, float], ...]:
    """The rows (t (s), P (Pa)) of the CSV file ``path``; ``quantity`` names the second column
    in the messages (``Q`` for a flow rate, m²/s; m³/s with ``axisymmetric``: the header's
    unit is checked against it).

    Guaranteed on return: at least 2 rows, every value a finite float, t strictly increasing.
    The file: a regular file of UTF-8 text (a byte-order mark allowed) of at most
    :data:`MAX_FILE_BYTES`; one row ``t, P`` per line, comma-separated; blank lines and lines
    starting with ``#`` are skipped; the first other line may be a header (no cell of it a
    number: ``t,P``). Raises
    :class:`WaveformError` naming the file (and the line) otherwise, ``OSError`` if the file
    cannot be read.
    """
    if not stat.S_ISREG(Path(path).stat().st_mode):  # a FIFO would block, a device not end
        raise WaveformError(f"{path}: not a regular file")
    with Path(path).open("rb") as f:
        raw = f.read(MAX_FILE_BYTES + 1)  # bounded, as a case file
    if len(raw) > MAX_FILE_BYTES:
        raise WaveformError(f"{path}: larger than {MAX_FILE_BYTES} bytes")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise WaveformError(
            f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} at offset {e.start})"
        ) from None
    rows: list[tuple[float, float]] = []
    header_allowed = True
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        cells = [cell.strip() for cell in line.split(",")]
        first, header_allowed = header_allowed, False
        values = [_decimal_or_none(cell) for cell in cells]
        if first and all(value is None for value in values):
            _check_header_units(cells, quantity, f"{path}: line {number}", axisymmetric)
            continue  # the header
        where = f"{path}: line {number}"
        if len(cells) != 2:
            raise WaveformError(f"{where}: expected 2 columns t, {quantity}, got {len(cells)}")
        for cell, value in zip(cells, values):
            if value is None:
                raise WaveformError(f"{where}: {shorten(repr(cell), 40)} is not a number")
        t, y = values
        for name, number in (("t", t), (quantity, y)):
            if not math.isfinite(number):
                raise WaveformError(f"{where}: {name} = {number} is not a finite number")
        if rows and t <= rows[-1][0]:
            raise WaveformError(
                f"{where}: t = {t:g} is not after the previous row's t = {rows[-1][0]:g}"
            )
        rows.append((t, y))
    if len(rows) < 2:
        raise WaveformError(
            f"{path}: {len(rows)} row{'s' if len(rows) != 1 else ''} of t, {quantity}; at least 2 "
            "are needed"
        )
    return tuple(rows)


HEADER_UNITS = {"t": ("s",), "P": ("Pa",), "Q": ("m^2/s", "m²/s", "m2/s")}
"""The units a waveform file's header may give (``t (s), P (Pa)``): the ones the file is read
in. A header naming another (``t (ms)``, ``P (mmHg)``) is refused, not silently misread."""

PIPE_FLOW_UNITS = ("m^3/s", "m³/s", "m3/s")
"""The units of Q a header may give in an axisymmetric case, whose flow rate is a pipe's
(docs/axisymmetric.md), where :data:`HEADER_UNITS` has the plane model's m²/s per unit depth."""


def _check_header_units(
    cells: list[str], quantity: str, where: str, axisymmetric: bool = False
) -> None:
    """Raise :class:`WaveformError` if a header cell names a unit, in parentheses or brackets,
    other than the one its column is read in (t in s; P in Pa or Q in m²/s, m³/s when
    ``axisymmetric``)."""
    for cell, name in zip(cells, ("t", quantity)):
        units = PIPE_FLOW_UNITS if axisymmetric and name == "Q" else HEADER_UNITS[name]
        found = re.search(r"[(\[]\s*([^)\]]*?)\s*[)\]]", cell)
        if found is None or found.group(1) in units:
            continue
        model = " (an axisymmetric case's flow rate)" if units is PIPE_FLOW_UNITS else ""
        raise WaveformError(
            f"{where}: the header gives {name} in {found.group(1)!r}; the file is read with "
            f"{name} in {units[0]}{model} (convert the column, or leave the unit out)"
        )


_DECIMAL = re.compile(
    r"[-+]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?|inf|infinity|nan)", re.IGNORECASE
)
"""A number as CSV files spell it: decimal, an exponent allowed; inf and nan are read and
refused after, as not finite. Python's ``float`` also takes ``1_000`` (its digit grouping),
which no spreadsheet writes: read as 1000 it would hide a typo, so it is not a number."""


def _decimal_or_none(cell: str) -> float | None:
    """The float ``cell`` spells (:data:`_DECIMAL`), or None."""
    if not _DECIMAL.fullmatch(cell):
        return None
    return float(cell)


HARMONIC_SAMPLES = 256
"""Samples of a periodic flow rate Q over one period [0, T) for its discrete Fourier transform
(the Womersley inlet profile's harmonics, fsi.physics.inflow_profiles)."""


def sample_times(period: float):
    """The :data:`HARMONIC_SAMPLES` times j T / N, j = 0 … N − 1, in [0, T) (s), a numpy array."""
    return period * np.arange(HARMONIC_SAMPLES) / HARMONIC_SAMPLES
