"""Fixtures shared by the command tests: one short ``livedic run`` recording for export, replay and report."""

import pytest

from livedic.stream.cli import main

@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    """Errors as users see them (one line), not LIVEDIC_DEBUG's traceback, whatever the caller's environment."""
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


def livedic_lines(err):
    """The ``livedic: ...`` lines of a command's stderr (which must hold no traceback)."""
    assert "Traceback" not in err, err
    return [line for line in err.splitlines() if line.startswith("livedic: ")]


SHORT_SOURCE = "synthetic:tensile?frames=4&size=192x256&pace=0"


@pytest.fixture(scope="package")
def short_run(tmp_path_factory):
    """A 4-frame simulated tensile test recorded by ``livedic run`` with the simulator's force (``--load
    synthetic``, recorded on /machine/force) and a 100 px axial extensometer: the path of the .mcap."""
    path = tmp_path_factory.mktemp("short_run") / "short.mcap"
    code = main(["run", "--source", SHORT_SOURCE, "--load", "synthetic", "--record", str(path), "--viewer", "none",
                 "--progress", "off", "--gauge-length", "100", "--static-frames", "0"])
    assert code == 0 and path.exists()
    return str(path)
