"""The import graph of the project's packages: no cycles (type-checking imports included) and no
import from a lower layer to a higher one (docs/design.md, "Packages and layers")."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("inest_common", "inest_sim_node", "inest_reward_node", "inest_agent_node", "inest_experiments")
# module prefix -> the prefixes it may import (itself always); the longest matching prefix decides
ALLOWED = {
    "inest_common": (),
    "inest_sim_node": ("inest_common",),
    "inest_reward_node.runtime": ("inest_common",),
    "inest_reward_node.node": ("inest_common", "inest_reward_node.runtime"),
    "inest_reward_node.gym_wrapper": ("inest_reward_node.runtime",),
    "inest_reward_node.learning": ("inest_common", "inest_sim_node", "inest_reward_node.runtime"),
    "inest_reward_node.recordings": (
        "inest_common",
        "inest_sim_node",
        "inest_reward_node.runtime",
        "inest_reward_node.learning",
    ),
    "inest_agent_node": ("inest_common", "inest_sim_node", "inest_reward_node"),
    "inest_experiments": ("inest_common", "inest_sim_node", "inest_reward_node", "inest_agent_node"),
}


def module_name(path: Path) -> str:
    parts = path.relative_to(path.parents[len(path.relative_to(ROOT).parts) - 2]).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_modules() -> dict[str, Path]:
    modules = {}
    for package in PACKAGES:
        for path in (ROOT / package / package).rglob("*.py"):
            modules[module_name(path)] = path
    return modules


def imports_of(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """Every project module `name` imports, at any depth of its code (TYPE_CHECKING blocks too)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            targets = [f"{base}.{alias.name}" for alias in node.names] + [base]
        else:
            continue
        found.update(target for target in targets if target in known and target != name)
    return found


def layer(name: str) -> str:
    return max((prefix for prefix in ALLOWED if name == prefix or name.startswith(prefix + ".")), key=len)


def test_no_import_cycles_and_no_import_up_the_layers():
    known = project_modules()
    assert "inest_reward_node.runtime.rewards" in known and "inest_reward_node.learning.quality" in known
    graph = {name: imports_of(name, path, known) for name, path in known.items()}
    upward = [
        f"{name} -> {target}"
        for name, targets in graph.items()
        for target in targets
        if layer(target) != layer(name)
        and not any(target == p or target.startswith(p + ".") for p in ALLOWED[layer(name)])
    ]
    assert upward == []
    cycles, state = [], {}

    def visit(name: str, trail: list[str]) -> None:
        state[name] = "open"
        for target in sorted(graph[name]):
            if state.get(target) == "open":
                cycles.append(" -> ".join([*trail[trail.index(target) :], target]))
            elif target not in state:
                visit(target, [*trail, target])
        state[name] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert cycles == []


def test_experiments_use_only_public_names_of_the_other_packages():
    """inest_experiments is tooling on the other packages' public APIs: it imports no name with a
    leading underscore from them and reads no such attribute of a module it imported from them."""
    private = []
    for path in (ROOT / "inest_experiments" / "inest_experiments").rglob("*.py"):
        tree = ast.parse(path.read_text())
        modules = set()  # local names bound to modules of the other packages
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("inest_"):
                if not node.module.startswith("inest_experiments"):
                    private += [f"{path.name}: {node.module}.{a.name}" for a in node.names if a.name.startswith("_")]
                    modules |= {a.asname or a.name for a in node.names}
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("inest_") and not alias.name.startswith("inest_experiments"):
                        private += [f"{path.name}: {alias.name}"] if "._" in alias.name else []
                        modules.add(alias.asname or alias.name.split(".")[0])
        private += [
            f"{path.name}: {node.value.id}.{node.attr}"
            for node in ast.walk(tree)
            if isinstance(node, ast.Attribute)
            and node.attr.startswith("_")
            and not node.attr.startswith("__")
            and isinstance(node.value, ast.Name)
            and node.value.id in modules
        ]
    assert private == []
