"""The README's Python snippets run as written (each ```python block, from a scratch folder)."""
import re
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), flags=re.S | re.M)


def test_readme_has_python_snippets():
    assert BLOCKS


@pytest.mark.parametrize("code", BLOCKS, ids=[f"block{i + 1}" for i in range(len(BLOCKS))])
def test_readme_snippet_runs(code, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("LINKFEA_CACHE_DIR", str(tmp_path / ".cache" / "meshes"))
    try:
        exec(compile(code, f"{README.name} snippet", "exec"), {"__name__": "__readme__"})
    finally:
        plt.close("all")
