"""Experiment-grid configuration (`inest-experiments`), one typed place, loadable from YAML: the grid
files stay in the agent's config folder (`inest_agent_node/config/grid.yaml` and the others)."""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from inest_common.settings import reject_unknown

from inest_agent_node.config import read_yaml_mapping

# inest-train flags an experiment grid sets for every cell itself (experiments.py); `model` has its own key
GRID_FLAGS = ("--config", "--out", "--seed", "--threads", "--total-steps", "--resume", "--model")
METHOD_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")  # a method is a folder name


@dataclass(frozen=True)
class ReferenceResult:
    """A published result to set beside a method's own (the thesis's, for the shipped grid): its
    mean score and its success rate (a fraction), as the source reports them."""

    score: float
    success: float | None = None

    def check(self, method: str) -> None:
        for name in ("score", "success"):
            value = getattr(self, name)
            if value is None and name == "success":
                continue
            if type(value) not in (int, float) or not 0 <= value <= 1:
                raise ValueError(f"method {method}: reference {name} must be a number in [0, 1], got {value!r}")


@dataclass(frozen=True)
class MethodConfig:
    """One method of an experiment grid: the inest-train flags that make it, the reward model
    folder it reads (none for the oracle), optionally a published result to compare with, and its
    own seeds where it needs more than the grid's (a headline row: 5)."""

    args: tuple[str, ...] = ()
    model: str | None = None
    reference: ReferenceResult | None = None
    seeds: tuple[int, ...] | None = None  # None: the grid's

    def check(self, name: str) -> None:
        if not METHOD_NAME.fullmatch(name):
            raise ValueError(f"method name {name!r} must be a folder name (letters, digits, '.', '_', '-')")
        if not all(isinstance(arg, str) for arg in self.args):
            raise ValueError(f"method {name}: args must be a list of inest-train flags and values (strings)")
        taken = sorted({arg.split("=")[0] for arg in self.args} & set(GRID_FLAGS))
        if taken:
            raise ValueError(f"method {name}: the grid sets {taken} itself (the reward model folder is `model:`)")
        if self.model is not None and not isinstance(self.model, str):
            raise ValueError(f"method {name}: model must be a folder path, got {self.model!r}")
        if self.reference is not None:
            self.reference.check(name)
        if self.seeds is not None:
            check_seeds(self.seeds, f"method {name}: ")


def check_seeds(seeds: tuple[int, ...], where: str = "") -> None:
    if not seeds or not all(type(seed) is int and seed >= 0 for seed in seeds):
        raise ValueError(f"{where}seeds must be a non-empty list of integers >= 0, got {list(seeds)}")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"{where}seeds must differ, got {list(seeds)}")


def check_cell_text(text: object, what: str) -> None:
    """Text the report prints in a heading or a table cell: one line, not blank, no '|'."""
    if not isinstance(text, str) or not text.strip() or "\n" in text or "|" in text:
        raise ValueError(f"{what} must be one line of text without '|', got {text!r}")


@dataclass(frozen=True)
class TableConfig:
    """A comparison the report shows as its own table and learning-curve figure, like one of the
    thesis's tables: a title and the grid's methods it compares."""

    title: str
    methods: tuple[str, ...]


@dataclass(frozen=True)
class GridConfig:
    """An experiment grid (`inest-experiments`): every method trained with every seed for
    `total_steps` from the training settings in `config`, each run in `out/<method>/seed<N>/`.
    Relative paths are read from the working directory (the checkout's root)."""

    methods: dict[str, MethodConfig]
    seeds: tuple[int, ...] = (0, 1, 2)
    total_steps: int = 500_000
    config: str = "inest_agent_node/config/train.yaml"
    out: str = "runs/grid"
    # a demonstration dataset: the report scores every method's reward model on its validation
    # split (reward MSE / MAE against the environment's reward); none: no quality table
    demos: str | None = None
    # comparisons, each its own table and figure in the report (none: one table of every method)
    tables: dict[str, TableConfig] = field(default_factory=dict)
    # the column the methods' `reference` results are shown in, naming where they come from
    reference_label: str = "reference"

    def __post_init__(self) -> None:
        if not self.methods:
            raise ValueError("the grid lists no methods")
        for name, method in self.methods.items():
            method.check(name)
        check_seeds(self.seeds)
        if type(self.total_steps) is not int or self.total_steps <= 0:
            raise ValueError(f"total_steps must be a positive integer, got {self.total_steps!r}")
        for name in ("config", "out"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"{name} must be a path, got {getattr(self, name)!r}")
        if self.demos is not None and (not isinstance(self.demos, str) or not self.demos):
            raise ValueError(f"demos must be a dataset folder, got {self.demos!r}")
        for key, table in self.tables.items():
            if not isinstance(key, str) or not METHOD_NAME.fullmatch(key):
                raise ValueError(f"table name {key!r} must be a file name (letters, digits, '.', '_', '-')")
            check_cell_text(table.title, f"table {key}: title")
            unknown = [method for method in table.methods if not isinstance(method, str) or method not in self.methods]
            if not table.methods or unknown:
                raise ValueError(f"table {key}: methods must be some of the grid's {list(self.methods)}, got {unknown}")
            if len(set(table.methods)) != len(table.methods):
                raise ValueError(f"table {key}: methods must differ, got {list(table.methods)}")
        check_cell_text(self.reference_label, "reference_label")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GridConfig:
        reject_unknown(data, cls, "grid setting(s)")
        values = dict(data)
        methods = values.get("methods")
        if not isinstance(methods, dict):
            raise ValueError("the grid needs `methods`: a mapping of method name to {args: [...], model: ...}")
        parsed = {}
        for name, method in methods.items():
            method = method or {}
            if not isinstance(method, dict):
                raise ValueError(f"method {name} must be a mapping of args and model")
            reject_unknown(method, MethodConfig, f"setting(s) of method {name}")
            args = method.get("args") or []
            if not isinstance(args, list):
                raise ValueError(f"method {name}: args must be a list of inest-train flags and values")
            reference = method.get("reference")
            if reference is not None:
                if not isinstance(reference, dict):
                    raise ValueError(f"method {name}: reference must be a mapping of score and success")
                reject_unknown(reference, ReferenceResult, f"reference setting(s) of {name}")
                if "score" not in reference:
                    raise ValueError(f"method {name}: reference needs a score")
                reference = ReferenceResult(**reference)
            seeds = method.get("seeds")
            if seeds is not None:
                seeds = tuple(seeds) if isinstance(seeds, list) else (seeds,)
            parsed[str(name)] = MethodConfig(tuple(args), method.get("model"), reference, seeds)
        values["methods"] = parsed
        tables = values.get("tables")
        if tables is not None and not isinstance(tables, dict):
            raise ValueError("tables must be a mapping of table name to {title: ..., methods: [...]}")
        parsed_tables = {}
        for key, table in (tables or {}).items():
            if not isinstance(table, dict) or not isinstance(table.get("methods"), list):
                raise ValueError(f"table {key} must be a mapping of a title and a list of methods")
            reject_unknown(table, TableConfig, f"setting(s) of table {key}")
            parsed_tables[key] = TableConfig(title=table.get("title", str(key)), methods=tuple(table["methods"]))
        values["tables"] = parsed_tables
        if "seeds" in values:
            seeds = values["seeds"]
            values["seeds"] = tuple(seeds) if isinstance(seeds, list) else (seeds,)
        return cls(**values)

    def seeds_of(self, method: str) -> tuple[int, ...]:
        """The seeds `method` runs with: its own, or the grid's."""
        return self.methods[method].seeds or self.seeds

    @classmethod
    def from_yaml(cls, path: str | Path) -> GridConfig:
        return cls.from_dict(read_yaml_mapping(path, "grid settings (methods, seeds, total_steps, config, out)"))
