"""The documentation's examples are tests: every python block of docs/api.md,
docs/sweep.md, docs/doe.md and docs/parameters.md runs, in order, in the repository
folder (as a reader would run them after `make fmus`)."""
import os
import re
from pathlib import Path

import pytest

from tests.support.paths import ROOT


def python_blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)


@pytest.mark.parametrize("page, count", [("api.md", 4), ("sweep.md", 1), ("doe.md", 1),
                                         ("parameters.md", 3)])
def test_every_example_of_the_page_runs(built, page, count, monkeypatch):
    blocks = python_blocks(ROOT / "docs" / page)
    assert len(blocks) >= count
    monkeypatch.chdir(ROOT)
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, f"docs/{page}", "exec"), namespace)  # noqa: S102 (our own docs)
    assert os.getcwd() == str(ROOT)
