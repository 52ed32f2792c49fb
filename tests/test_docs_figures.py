"""Numbers that cannot drift: every figure in a results table of the README and the docs is
found in the committed result files the table names.

A table's sources are the result files (JSON or YAML under results/, or a folder or glob of them)
named in the table itself, in the lines just above it, or in a `<!-- figures: PATH ... -->`
comment above it. Each decimal number and percentage in a table cell (the first column names the
row and is not read) must equal a number in those files at the precision it is printed with (a
percentage: the number or a fraction times 100). Where the first column names a method, run or
folder (its code spans, or one word) that the files name, the row's figures must be in what
names it (the records with that name, the files in a folder of that name), so that a figure
cannot pass by matching another row's number (a row gathered from several records names each).
A table of settings rather than results says so with `<!-- not figures: WHY -->`.
"""

from __future__ import annotations

import glob
import json
import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
ABOVE = 8  # lines above a table searched for its sources
SEPARATOR = re.compile(r"^\|[-:| ]+\|$")
FIGURE = re.compile(r"(?<![\w.\-/])(-?\d+\.\d+)(\s?%)?|(?<![\w.\-/])(\d+)(\s?%)")
SOURCE = re.compile(r"results/[\w./*\-]+")
MARKER = re.compile(r"<!-- figures: (.*?) -->")


def pages() -> list[Path]:
    """The README and every page under docs/, the reports in docs/reports/ included."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def tables(page: Path) -> list[tuple[int, str, list[str]]]:
    """(line number, the text above, the data rows) of every table with a figure in it."""
    lines = page.read_text().splitlines()
    found, index = [], 0
    while index < len(lines):
        if lines[index].startswith("|") and index + 1 < len(lines) and SEPARATOR.match(lines[index + 1]):
            start, index = index, index + 2
            while index < len(lines) and lines[index].startswith("|"):
                index += 1
            rows = lines[start + 2 : index]
            if any(FIGURE.search("|".join(row.split("|")[2:])) for row in rows):
                found.append((start + 1, "\n".join(lines[max(0, start - ABOVE) : start]), rows))
        else:
            index += 1
    return found


def source_files(text: str) -> list[Path]:
    named = [path for marker in MARKER.findall(text) for path in marker.split()] + SOURCE.findall(text)
    files: list[Path] = []
    for name in named:
        name = name.rstrip(".,)`")
        for path in sorted(glob.glob(str(ROOT / name))) if "*" in name else [str(ROOT / name)]:
            path = Path(path)
            if path.is_dir():
                files += sorted(p for p in path.rglob("*") if p.suffix in (".json", ".yaml"))
            elif path.suffix in (".json", ".yaml") and path.is_file():
                files.append(path)
    return files


def numbers(value: object, out: list[float]) -> list[float]:
    if isinstance(value, int | float) and not isinstance(value, bool):
        out.append(float(value))
    elif isinstance(value, dict):
        for item in value.values():
            numbers(item, out)
    elif isinstance(value, list):
        for item in value:
            numbers(item, out)
    return out


def names_one(text: str, names: set[str]) -> bool:
    """Whether `text` is one of `names`, or a path or run that ends or starts with it
    (`results/x/NAME`, `NAME/seed0`)."""
    return any(text == name or text.endswith("/" + name) or text.startswith(name + "/") for name in names)


def named_records(value: object, names: set[str], out: list[object]) -> list[object]:
    """The objects (at any depth) that name one of `names`: by a string entry, or as the entry
    of a key that does."""
    if isinstance(value, dict):
        if any(isinstance(item, str) and names_one(item, names) for item in value.values()):
            out.append(value)
        out += [item for key, item in value.items() if names_one(str(key), names)]
        for item in value.values():
            named_records(item, names, out)
    elif isinstance(value, list):
        for item in value:
            named_records(item, names, out)
    return out


def row_names(row: str) -> set[str]:
    """What a row's first column names: its `code` spans that are not paths, or the cell itself
    when it is one word."""
    first = row.split("|")[1].strip()
    names = {span for span in re.findall(r"`([^`]+)`", first) if "/" not in span}
    return names or ({first} if first and " " not in first and "/" not in first else set())


def row_sources(files: list[Path], loaded: list[object], names: set[str]) -> list[object]:
    """What a row that names its method, run or folder is read from: the files of that name (or
    in a folder of that name) and the records that name it."""
    named_files = [
        data
        for path, data in zip(files, loaded, strict=True)
        if names & set(path.parts[:-1]) or any(path.stem == name or path.stem.startswith(name + "-") for name in names)
    ]
    return named_files + named_records(loaded, names, [])


def printed(token: str, values: list[float], percent: bool, minutes: bool) -> bool:
    """Whether a number printed as `token` is one of `values` at that precision: a percentage
    may be stored as a fraction, a figure in minutes as seconds."""
    digits = len(token.partition(".")[2])
    target, tolerance = float(token), 0.5 * 10**-digits + 1e-9  # rounded either way at a half
    return any(
        abs(candidate - target) <= tolerance
        for value in values
        for candidate in (value, 100 * value if percent or digits else value, value / 60 if minutes else value)
    )


CASES = [(page, line, above, rows) for page in pages() for line, above, rows in tables(page)]


@pytest.mark.parametrize(
    ("page", "line", "above", "rows"), CASES, ids=[f"{page.relative_to(ROOT)}:{line}" for page, line, _, _ in CASES]
)
def test_every_figure_of_a_results_table_is_in_the_result_files_it_names(page, line, above, rows):
    if "<!-- not figures:" in above:
        return
    files = source_files(above + "\n" + "\n".join(rows))
    assert files, f"{page.name}:{line}: the table names no result file (add <!-- figures: PATH --> above it)"
    loaded = [
        json.loads(path.read_text()) if path.suffix == ".json" else yaml.safe_load(path.read_text()) for path in files
    ]
    values = numbers(loaded, [])
    # a row that names what it reports (a method, a run) is read from what names it
    row_values = {row: numbers(row_sources(files, loaded, row_names(row)), []) or values for row in rows}
    missing = [
        match.group(0).strip()
        for row in rows
        for cell in row.replace("\u2212", "-").split("|")[2:]  # a typeset minus is a minus
        for match in FIGURE.finditer(cell)
        if (match.group(1) or match.group(4))
        and not printed(
            match.group(1) or match.group(3),
            row_values[row],
            percent=bool(match.group(2) or match.group(4)),
            minutes=cell[match.end() :].lstrip().startswith("minute"),
        )
    ]
    assert not missing, f"{page.name}:{line}: {missing} are in none of {[str(p.relative_to(ROOT)) for p in files]}"
