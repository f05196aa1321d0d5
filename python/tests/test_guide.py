"""The Python chapter of the guide (docs/python.md) runs as written: every ```python block,
in order, in one namespace, in a fresh folder."""

import os
import re

from conftest import REPO, scripts_path


def test_the_python_guide_runs(tmp_path, monkeypatch):
    text = (REPO / "docs" / "python.md").read_text()
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)
    assert len(blocks) >= 3
    monkeypatch.chdir(tmp_path)
    # The guide's reader has the environment's `gelrig` command on the PATH.
    monkeypatch.setenv("PATH", f"{scripts_path()}{os.pathsep}{os.environ['PATH']}")
    namespace: dict = {}
    for k, block in enumerate(blocks, start=1):
        try:
            exec(compile(block, f"docs/python.md block {k}", "exec"), namespace)
        except Exception as e:
            raise AssertionError(f"docs/python.md, python block {k} failed: {e!r}\n{block}") from e
    assert (tmp_path / "force-depth.png").stat().st_size > 1000
    assert os.path.isfile(tmp_path / "portable.yaml")
