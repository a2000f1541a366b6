"""The size bars of issue #48, checked on every module of fsi/: no module over 600 lines, no
class over 300, no function (or method) over 60. ``OVER`` lists what is over a bar today and
why; the test fails on anything else over a bar, and on an entry of ``OVER`` that is no longer
over (so the list stays true)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODULE_LINES, CLASS_LINES, FUNCTION_LINES = 600, 300, 60

OVER: dict[str, str] = {}
"""Known excesses: ``path`` (a module), ``path:Class``, ``path:Class.method`` or
``path:function``."""


def sizes(path: Path, root: Path = ROOT) -> dict[str, tuple[int, int]]:
    """Every module, class and function of ``path``: name (relative to ``root``) → (lines,
    bar)."""
    text = path.read_text()
    name = str(path.relative_to(root))
    found = {name: (len(text.splitlines()), MODULE_LINES)}

    def walk(node, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                qualified = f"{prefix}{child.name}"
                bar = CLASS_LINES if isinstance(child, ast.ClassDef) else FUNCTION_LINES
                found[f"{name}:{qualified}"] = (child.end_lineno - child.lineno + 1, bar)
                walk(child, qualified + ".")

    walk(ast.parse(text), "")
    return found


def over(paths, root: Path = ROOT) -> dict[str, int]:
    """What is over its bar, with its size."""
    return {
        k: lines for path in paths for k, (lines, bar) in sizes(path, root).items() if lines > bar
    }


def test_nothing_but_the_known_excesses_is_over_a_bar():
    found = over(sorted((ROOT / "fsi").rglob("*.py")))
    assert set(found) - set(OVER) == set(), found
    assert set(OVER) - set(found) == set(), "no longer over a bar: take it out of OVER"


def test_a_long_function_is_found(tmp_path):
    """The check can fail: a function of 61 lines is over its bar, one of 60 is not."""
    body = "".join(f"    x{i} = {i}\n" for i in range(60))
    (tmp_path / "long.py").write_text(f"def f():\n{body}")
    (tmp_path / "short.py").write_text(f"def g():\n{body[: body.rindex('    x59')]}")
    assert over([tmp_path / "long.py", tmp_path / "short.py"], tmp_path) == {"long.py:f": 61}
