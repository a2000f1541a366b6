"""README's map of the code (its "Map of the code" block) against the tree: every folder of
fsi/ and every module of fsi/'s top level has an entry, and each folder's entry names exactly
its modules (``name (what it holds)`` items separated by ``·`` or ``─►``; the text in
parentheses is description)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"fsi.geometry": ROOT / "geometry"}
"""Map keys that are not paths: the geometry/ folder is installed as fsi.geometry."""


def map_entries(readme: str) -> dict[str, str]:
    """The map's entries: key (``fsi/config/``, ``fsi/cli.py``, ``fsi.geometry``) → its text."""
    block = readme.split("## Map of the code", 1)[1].split("\n\n    ", 1)[1]
    entries: dict[str, str] = {}
    key = None
    for line in ("    " + block).splitlines():
        if not line.startswith("    "):
            break
        if not line.startswith("     "):  # a new entry: its key, then its text
            key, _, text = line.strip().partition(" ")
            entries[key] = text
        else:
            entries[key] += " " + line.strip()
    return entries


def named_modules(text: str) -> set[str]:
    """The names an entry lists: its items with the parenthesised descriptions left out."""
    while re.search(r"\([^()]*\)", text):
        text = re.sub(r"\([^()]*\)", "", text)
    return {item.strip() for item in re.split(r"·|─►", text) if item.strip()}


def modules(folder: Path) -> set[str]:
    return {p.stem for p in folder.glob("*.py") if p.stem not in ("__init__", "__main__")}


def test_every_folder_and_top_level_module_has_an_entry():
    entries = map_entries((ROOT / "README.md").read_text())
    folders = {f"fsi/{p.name}/" for p in (ROOT / "fsi").iterdir() if (p / "__init__.py").exists()}
    top = {f"fsi/{name}.py" for name in modules(ROOT / "fsi")}
    assert set(entries) == folders | top | set(FOLDERS)


def test_each_entry_names_exactly_its_modules():
    entries = map_entries((ROOT / "README.md").read_text())
    for key, text in entries.items():
        if key.endswith(".py"):
            assert (ROOT / key).is_file(), key
            assert named_modules(text) == set(), key
            continue
        folder = FOLDERS.get(key, ROOT / key)
        named, present = named_modules(text), modules(folder)
        assert named == present, f"{key}: missing {present - named}, not there {named - present}"


def test_a_missing_module_is_found():
    """The check can fail: an entry without one of its folder's modules."""
    entries = map_entries((ROOT / "README.md").read_text())
    text = entries["fsi/numerics/"].replace("newton", "")
    assert named_modules(text) != modules(ROOT / "fsi" / "numerics")


FIGURE = re.compile(
    r"\d[\d,]*(?:\.\d+)?"
    r"(?:×| ?%| triangles| steps| s\b| min\b| ms\b| mm\b| MPa| kPa| Pa\b| m/s| µm)"
)
"""A figure in README's prose: a number with a unit, a ratio or a count of cells or steps."""


def figures(readme: str) -> list[str]:
    """The figures README states in its prose (not in code blocks, inline code or the map)."""
    prose = re.sub(r"```.*?```", "", readme, flags=re.S)
    prose = re.sub(r"`[^`]*`", "", prose)
    prose = "\n".join(line for line in prose.splitlines() if not line.startswith("    "))
    return FIGURE.findall(re.sub(r"\s+", " ", prose))


def test_every_figure_in_the_readme_is_in_the_docs():
    """README states no number that docs/ does not (its figures are read from the docs: a
    change of a measurement is made in the docs first)."""
    docs = re.sub(r"\s+", " ", "\n".join(p.read_text() for p in (ROOT / "docs").glob("*.md")))
    stated = figures((ROOT / "README.md").read_text())
    assert {"3.6×", "3,204 triangles", "390 steps"} <= set(stated)  # the check reads them
    assert [f for f in stated if f not in docs] == []
    assert figures("runs in `12 s`, then 7.5 % of 17 steps\n\n    1.5×") == ["7.5 %", "17 steps"]
