"""The typed boundaries: mypy on livedic.dic, livedic.acquire and livedic.stream, clean.

The packages are folders mapped onto the one import name ``livedic`` by the editable install's finder
(``pyproject.toml``'s package-dir), which mypy cannot see: the test builds a throw-away tree of links,
``livedic/dic -> dic/`` and so on, and checks it as the packages a user imports. mypy's settings are in
``pyproject.toml`` (``[tool.mypy]``). That every public function and method is annotated is measured by
``scripts/house_metrics.py``; this test keeps the annotations there true.
"""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CHECKED = ("dic", "acquire", "stream")


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None,
                    reason="mypy is not installed (it is in the [test] extras: pip install -e '.[test]')")
@pytest.mark.parametrize("package", CHECKED)
def test_mypy_is_clean(package, tmp_path):
    tree = tmp_path / "tree" / "livedic"
    tree.mkdir(parents=True)
    for name in ("dic", "acquire", "stream", "bench"):
        (tree / name).symlink_to(REPO / name, target_is_directory=True)
    run = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(REPO / "pyproject.toml"),
                          "--cache-dir", str(tmp_path / "cache"), "-p", f"livedic.{package}"],
                         cwd=tree.parent, capture_output=True, text=True, timeout=600,
                         env={"MYPYPATH": str(tree.parent), "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-2000:]
