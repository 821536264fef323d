"""The README's Python snippets run as written, from the repository root, and its set-up lines are the
ones CI runs (.ci/run reads the second line; this checks the first installs and runs the demo)."""

from __future__ import annotations

import re

import pytest
from conftest import REPO

README = (REPO / "README.md").read_text(encoding="utf-8")
SNIPPETS = re.findall(r"```python\n(.*?)```", README, flags=re.S)


def test_the_readme_has_python_snippets():
    assert len(SNIPPETS) >= 2


@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_readme_snippet_runs(index, monkeypatch):
    monkeypatch.chdir(REPO)  # the snippets use the repository's relative paths (campaigns/, frames/)
    namespace: dict[str, object] = {"__name__": f"readme_snippet_{index}"}
    exec(compile(SNIPPETS[index], f"README.md python block {index + 1}", "exec"), namespace)


def test_the_first_set_up_line_installs_and_runs_the_demo():
    block = re.search(r"```bash\n(.*?)```", README, flags=re.S)
    assert block is not None
    first, second = block.group(1).strip().splitlines()[:2]
    assert "pip install ." in first and first.rstrip().endswith("workbench demo")
    assert "pytest" in second
