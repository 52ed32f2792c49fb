"""The README's Python snippets run as written, from the repository root (where the ament package
folders sit next to the installed packages) and from elsewhere."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SNIPPETS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.DOTALL)


def test_the_readme_has_python_snippets():
    assert SNIPPETS


@pytest.mark.parametrize("where", ["root", "elsewhere"])
@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_readme_snippet_runs(index, where, tmp_path):
    cwd = ROOT if where == "root" else tmp_path
    result = subprocess.run(
        [sys.executable, "-c", SNIPPETS[index]], cwd=cwd, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, f"snippet {index} from {cwd}:\n{SNIPPETS[index]}\n{result.stderr[-2000:]}"
