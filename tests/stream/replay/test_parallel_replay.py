"""``livedic replay --workers N`` / ``--cluster ADDRESS``: the frames measured on Dask give the sequential replay's
outputs (CSV rows in order, comparison verdict, reference moves and fractures at the same frames), and survive a
worker that dies.

One LocalCluster of 2 worker processes serves the module (started once: a few seconds, plus numba's cached
kernels loading in each worker on its first frame)."""

import csv
import os
import re

import numpy as np
import pytest

from livedic.stream.cli import main
from tests.stream.replay.test_replay import dropped  # noqa: F401 - the fixture: a recording with dropped frames

pytest.importorskip("distributed")

POSITION_TO_KILL = 5          # the frame (replay position) whose task kills its worker, once


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


def _record(path, *extra, source="synthetic:tensile?size=128x256&frames=12&noise=0.5&pace=0"):
    code = main(["run", "--source", source,
                 "--record", str(path), "--viewer", "none", "--n-points", "60", "--progress", "off",
                 "--static-frames", "0", *extra])
    assert code == 0 and path.exists()
    return str(path)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A short session recorded by ``livedic run`` with the reference kept (``--reference-update never``)."""
    return _record(tmp_path_factory.mktemp("never") / "session.mcap", "--reference-update", "never")


@pytest.fixture(scope="module")
def moved(tmp_path_factory):
    """The same test with the default ``--reference-update auto``: the 12 % strain moves the reference (3 times)."""
    return _record(tmp_path_factory.mktemp("auto") / "session.mcap")


@pytest.fixture(scope="module")
def broken(tmp_path_factory):
    """A test to fracture (30 % strain, fading paint, broken at frame 36 of 40): 14 reference moves, then
    the points across the crack separated."""
    return _record(tmp_path_factory.mktemp("fracture") / "session.mcap", "--n-points", "700",
                   source="synthetic:tensile?strain=0.30&neck=1.0&fade=0.2&fracture=1&size=256x384&frames=40&pace=0")


@pytest.fixture(scope="module")
def cluster():
    """The address of a LocalCluster of 2 worker processes (1 thread each), closed after the module."""
    import logging

    from distributed import LocalCluster

    from livedic.stream.replay.parallel_replay import LOCAL_SCHEDULER_OPTIONS
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                      scheduler_kwargs=LOCAL_SCHEDULER_OPTIONS, silence_logs=logging.ERROR) as local:
        yield local.scheduler_address


@pytest.fixture(scope="module")
def sequential(recording, tmp_path_factory):
    """The sequential replay's CSV rows and its verdict line."""
    out = tmp_path_factory.mktemp("sequential") / "seq.csv"
    return _replay(recording, out)


def _replay(recording, out, *extra, capsys=None):
    import contextlib
    import io
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["replay", recording, "-o", str(out), "--progress", "off", *extra])
    assert code == 0, err.getvalue()
    if str(out).endswith(".parquet"):
        import pyarrow.parquet as pq

        from tests.stream.replay.test_rows import csv_like
        rows = csv_like(pq.read_table(out))
    else:
        with open(out, newline="") as f:
            rows = list(csv.reader(f))
    verdict = [line for line in err.getvalue().splitlines() if "replay matches" in line or "replay agrees" in line
               or "replay differs" in line]
    return rows, verdict, err.getvalue()


def _assert_same(parallel, sequential, *, verdict=True):
    """Same header, same (frame, point) rows in the same order, ok/status equal, numbers within the replay's rounding
    tolerances (u, v and the strains 1e-4, ZNCC ``ROUNDING_TOLERANCE_ZNCC``; and the same verdict line: ``verdict``)."""
    from livedic.stream.replay.agreement import ROUNDING_TOLERANCE_PX, ROUNDING_TOLERANCE_ZNCC
    rows, _, _ = parallel
    seq_rows, seq_verdict, _ = sequential
    assert rows[0] == seq_rows[0]
    assert len(rows) == len(seq_rows)
    header = rows[0]
    keys = [tuple(r[:3]) for r in rows[1:]]
    assert keys == [tuple(r[:3]) for r in seq_rows[1:]]
    assert len(set(keys)) == len(keys)                       # every (frame, timestamp, point) exactly once
    a = np.array([[float(v) for v in r] for r in rows[1:]])
    b = np.array([[float(v) for v in r] for r in seq_rows[1:]])
    for name in ("ok", "status"):
        column = header.index(name)
        assert np.array_equal(a[:, column], b[:, column]), name
    scale = [("u_mm", 1e-4), ("v_mm", 1e-4)] if "u_mm" in header else []
    for name, tolerance in [("u", ROUNDING_TOLERANCE_PX), ("v", ROUNDING_TOLERANCE_PX), ("zncc", ROUNDING_TOLERANCE_ZNCC),
                            ("exx", 1e-4), ("eyy", 1e-4)] + scale:
        column = header.index(name)
        assert np.array_equal(np.isnan(a[:, column]), np.isnan(b[:, column])), name
        both = np.isfinite(a[:, column])
        assert np.max(np.abs(a[both, column] - b[both, column])) <= tolerance, name
    if verdict is True:
        assert parallel[1] == seq_verdict


def test_parallel_replay_equals_sequential(recording, cluster, sequential, tmp_path):
    parallel = _replay(recording, tmp_path / "par.csv", "--cluster", cluster)
    _assert_same(parallel, sequential)
    assert len(sequential[0]) == 1 + 12 * 59                   # 12 frames x 59 points (the grid for 60 wanted)
    assert "replay matches the recording exactly" in sequential[1][0]
    assert "parallel: 12 frames measured on the Dask scheduler at" in parallel[2]


def test_parallel_replay_to_parquet_holds_the_sequential_rows(recording, cluster, sequential, tmp_path):
    """For Parquet the workers send each frame's columns, not CSV lines: the same rows and verdict."""
    parallel = _replay(recording, tmp_path / "par.parquet", "--cluster", cluster)
    _assert_same(parallel, sequential)


def test_with_a_scale_both_writers_add_the_same_mm_columns(recording, cluster, tmp_path):
    """``--scale``: ``u_mm, v_mm`` after the strains (export's fields.csv columns), from the sequential and the
    parallel writers alike, CSV and Parquet; without a calibration they are u, v / px_per_mm."""
    sequential = _replay(recording, tmp_path / "seq.csv", "--scale", "8")
    header = sequential[0][0]
    assert header[-5:] == ["exx", "eyy", "exy", "u_mm", "v_mm"]
    values = np.array([[float(v) for v in r] for r in sequential[0][1:]])
    for px, mm in (("u", "u_mm"), ("v", "v_mm")):
        np.testing.assert_allclose(values[:, header.index(mm)], values[:, header.index(px)] / 8.0, rtol=1e-12)
    for name in ("par.csv", "par.parquet"):
        _assert_same(_replay(recording, tmp_path / name, "--scale", "8", "--cluster", cluster), sequential)


class KillOnce:
    """A worker plugin: the worker that starts the task of replay position ``POSITION_TO_KILL`` dies (os._exit),
    once (the flag file is removed first), as a worker lost to a crash or a pre-empted node."""

    def __init__(self, flag):
        self.flag = flag

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and str(key).startswith("livedic-replay-frame-") \
                and str(key).endswith(f"-{POSITION_TO_KILL}"):
            try:
                os.remove(self.flag)
            except FileNotFoundError:
                return
            os._exit(1)


def _replay_killing_once(recording, address, tmp_path):
    """The replay on the cluster at ``address`` while a worker dies as it starts the flagged frame."""
    import cloudpickle
    from distributed import Client
    from distributed.diagnostics.plugin import WorkerPlugin

    import tests.stream.replay.test_parallel_replay as this
    cloudpickle.register_pickle_by_value(this)          # the workers need not import the test module

    class Plugin(KillOnce, WorkerPlugin):
        pass

    flag = tmp_path / "kill-once"
    flag.write_text("the first worker to start the flagged frame removes this and dies\n")
    with Client(address, set_as_default=False) as client:
        client.register_plugin(Plugin(str(flag)), name="kill-once")
        try:
            parallel = _replay(recording, tmp_path / "par.csv", "--cluster", address)
        finally:
            client.unregister_worker_plugin("kill-once")
    assert not flag.exists()                            # a worker did die on that frame
    return parallel


def test_worker_killed_mid_replay_still_gives_every_frame_once(recording, cluster, sequential, tmp_path):
    _assert_same(_replay_killing_once(recording, cluster, tmp_path), sequential)


def test_the_only_worker_killed_loses_nothing(recording, sequential, tmp_path):
    """With one worker, its death loses everything it held (the reference, finished frames): the scheduler
    computes them again from their tasks when the nanny has restarted it."""
    import logging

    from distributed import LocalCluster

    from livedic.stream.replay.parallel_replay import LOCAL_SCHEDULER_OPTIONS
    with LocalCluster(n_workers=1, processes=True, threads_per_worker=1, dashboard_address=None,
                      scheduler_kwargs=LOCAL_SCHEDULER_OPTIONS, silence_logs=logging.CRITICAL) as local:
        _assert_same(_replay_killing_once(recording, local.scheduler_address, tmp_path), sequential)


def test_workers_option_starts_its_own_local_cluster(recording, sequential, tmp_path):
    _assert_same(_replay(recording, tmp_path / "par.csv", "--workers", "2"), sequential)


def test_bad_cluster_address_one_line_exit_2_nothing_written(recording, tmp_path, capsys, monkeypatch):
    import livedic.stream.replay.parallel_replay as parallel_replay
    monkeypatch.setattr(parallel_replay, "FIRST_CONNECT_TIMEOUT_S", 1)
    out = tmp_path / "out.csv"
    code = main(["replay", recording, "-o", str(out), "--progress", "off", "--cluster", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("livedic: error: --cluster tcp://127.0.0.1:9: no Dask scheduler")
    assert not out.exists() and os.listdir(tmp_path) == []


def _replay_in_a_new_process(recording, out, cluster):
    """``livedic replay`` in a process of its own: what a user sees on stderr (a ``Client.__del__`` traceback at
    exit included), and its exit code. The timeout only keeps a hung replay from hanging the suite."""
    import subprocess
    import sys
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", "replay", recording, "-o", str(out),
                           "--progress", "off", "--cluster", cluster], capture_output=True, text=True, timeout=180)
    return done.returncode, done.stderr


@pytest.mark.parametrize("address, says", [
    ("nonsense://x", "unknown scheme 'nonsense'"),
    ("", "no scheduler address"),
    ("tcp://127.0.0.1", "not HOST:PORT after tcp://"),
    ("127.0.0.1:99999", "port 99999 out of 1-65535"),
    ("tcp://:8786", "no host"),
])
def test_a_malformed_cluster_address_is_one_line_and_nothing_else(recording, tmp_path, address, says):
    """Refused before any Client exists: no half-started Client left whose ``__del__`` prints a traceback."""
    out = tmp_path / "out.csv"
    code, err = _replay_in_a_new_process(recording, out, address)
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("livedic: error: --cluster ") and says in err, err
    assert not out.exists() and os.listdir(tmp_path) == []


def test_no_scheduler_at_a_well_formed_address_is_one_line_naming_the_wait(recording, tmp_path):
    """A port bound but not listening refuses every connection: one line saying how long it waited."""
    import socket

    from livedic.stream.replay.parallel_replay import FIRST_CONNECT_TIMEOUT_S
    out = tmp_path / "out.csv"
    with socket.socket() as closed:
        closed.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{closed.getsockname()[1]}"
        code, err = _replay_in_a_new_process(recording, out, address)
    assert code == 2, err
    assert err == (f"livedic: error: --cluster {address}: no Dask scheduler answered at {address} within "
                   f"{FIRST_CONNECT_TIMEOUT_S:g} s; start one with `dask scheduler`, or use --workers N\n")
    assert not out.exists() and os.listdir(tmp_path) == []


@pytest.mark.parametrize("address", ["tcp://10.0.0.5:8786", "10.0.0.5:8786", "sched.example:8786", "[::1]:8786",
                                     "tls://10.0.0.5:8786", "ws://h:1", "wss://h:65535", "inproc://10.0.0.5/42/1"])
def test_the_addresses_distributed_reads_pass_the_form_check(address):
    from livedic.stream.replay.parallel_replay import check_cluster_address
    assert check_cluster_address(address) == address


def test_a_scheduler_given_as_host_port_without_scheme(recording, cluster, sequential, tmp_path):
    """``HOST:PORT``: distributed's default scheme, tcp."""
    assert cluster.startswith("tcp://")
    _assert_same(_replay(recording, tmp_path / "par.csv", "--cluster", cluster[len("tcp://"):]), sequential)


def _events(stderr):
    """The session's reference-move and fracture lines, without their timings."""
    return [re.sub(r", [0-9.]+ ms$", "", line) for line in stderr.splitlines() if line.startswith("livedic: warning:")
            and ("reference moved" in line or "fracture" in line)]


def test_reference_moves_are_followed_as_sequentially(moved, cluster, tmp_path):
    """The default ``auto`` moves the reference at frames 7, 10 and 11: the workers' trackers move it there too,
    and each frame after a move, started from the recorded result mapped onto the key frame, starts where the
    sequential tracker started it (which carries its own result through the same mapping): bit for bit."""
    sequential = _replay(moved, tmp_path / "seq.csv")
    parallel = _replay(moved, tmp_path / "par.csv", "--cluster", cluster)
    _assert_same(parallel, sequential)
    assert parallel[0] == sequential[0]                     # every CSV line: the numbers at full precision
    assert "replay matches the recording exactly" in sequential[1][0]
    # the recording shows the moves at 7 and 10: nothing was measured ahead of them against the old reference
    assert "3 reference move(s) or fracture(s): 0 frame(s) measured ahead" in parallel[2]


def test_a_fracture_and_its_key_frames_are_followed_as_sequentially(broken, cluster, tmp_path):
    sequential = _replay(broken, tmp_path / "seq.csv")
    parallel = _replay(broken, tmp_path / "par.csv", "--cluster", cluster)
    _assert_same(parallel, sequential)
    assert parallel[0] == sequential[0]                     # bit for bit through 14 moves and the fracture
    events = _events(sequential[2])
    assert any("fracture" in line for line in events) and events == _events(parallel[2])
    header = sequential[0][0]
    separated = [r for r in parallel[0][1:] if int(r[header.index("status")]) == 11]     # Status.SEPARATED
    assert separated and all(r[header.index("u")] == "nan" for r in separated)


def test_a_reference_update_asked_for_on_replay_is_followed(recording, cluster, tmp_path):
    """The recording kept its reference; asked to move it every 5 frames, both replays move it at frames 4 and 9
    (counting as the live tracker counts: the reference frame is the first frame since the key frame). The seeds
    are the recording's results against frame 0, not the moved replay's own: within 1e-4 px, not 1e-12."""
    sequential = _replay(recording, tmp_path / "seq.csv", "--reference-update", "every:5")
    parallel = _replay(recording, tmp_path / "par.csv", "--cluster", cluster, "--reference-update", "every:5")
    _assert_same(parallel, sequential, verdict=False)
    # moves the recording does not show: the frames measured ahead of them were measured again
    assert re.search(r"2 reference move\(s\) or fracture\(s\): [1-9][0-9]* frame\(s\) measured ahead", parallel[2])


def test_shared_path_workers_read_the_frames_themselves(recording, cluster, sequential, tmp_path):
    parallel = _replay(recording, tmp_path / "par.csv", "--cluster", cluster, "--shared-path")
    _assert_same(parallel, sequential)
    assert f"the images read by the workers from {os.path.abspath(recording)}" in parallel[2]


@pytest.mark.parametrize("option", [["--workers", "0"], ["--workers", "2", "--cluster", "tcp://127.0.0.1:9"]])
def test_bad_parallel_options_one_line_exit_2(recording, tmp_path, capsys, option):
    out = tmp_path / "out.csv"
    code = main(["replay", recording, "-o", str(out), "--progress", "off", *option])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("livedic: error: ")
    assert not out.exists()


def test_the_shipped_sample_recorded_on_another_machine(cluster, tmp_path):
    """recordings/sample-tensile.mcap was recorded on another CPU: both replays agree with it within rounding, and
    with each other within 1e-4 px (the parallel one starts each frame from the recorded result before it, the
    sequential one from its own)."""
    sample = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))),
                          "recordings", "sample-tensile.mcap")
    sequential = _replay(sample, tmp_path / "seq.csv")
    parallel = _replay(sample, tmp_path / "par.csv", "--cluster", cluster)
    assert sequential[1][0].startswith("livedic: replay agrees with the recording within floating-point rounding")
    assert parallel[1][0].startswith("livedic: replay agrees with the recording within floating-point rounding")
    parallel = (parallel[0], sequential[1], parallel[2])      # the verdicts name their own max difference
    _assert_same(parallel, sequential)


def test_a_scheduler_without_workers_one_line_exit_2(recording, tmp_path, capsys, monkeypatch):
    import logging

    from distributed import LocalCluster

    import livedic.stream.replay.parallel_replay as parallel_replay
    from livedic.stream.replay.parallel_replay import LOCAL_SCHEDULER_OPTIONS
    monkeypatch.setattr(parallel_replay, "CONNECT_TIMEOUT_S", 1)
    out = tmp_path / "out.csv"
    with LocalCluster(n_workers=0, processes=True, dashboard_address=None, scheduler_kwargs=LOCAL_SCHEDULER_OPTIONS,
                      silence_logs=logging.CRITICAL) as bare:
        code = main(["replay", recording, "-o", str(out), "--progress", "off", "--cluster", bare.scheduler_address])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "the Dask scheduler has no worker (none joined within 1 s)" in err
    assert not out.exists()


def test_a_truncated_recording_replays_in_parallel_as_sequentially(cluster, tmp_path):
    """A recording cut short by a kill (paced, so its chunks were written as live; cut inside the last image
    chunk): both replays replay what can be recovered, the same; --shared-path says the file has no index."""
    from mcap.reader import make_reader
    path = tmp_path / "paced.mcap"
    _record(path, "--reference-update", "never", source="synthetic:tensile?size=128x256&frames=30&fps=25&noise=0.5")
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    images = {cid for cid, channel in summary.channels.items() if channel.topic == "/camera/image"}
    last = max((c for c in summary.chunk_indexes if set(c.message_index_offsets) & images),
               key=lambda c: c.chunk_start_offset)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:last.chunk_start_offset + last.chunk_length // 2])
    sequential = _replay(str(cut), tmp_path / "seq.csv")
    assert "is truncated" in sequential[2]
    _assert_same(_replay(str(cut), tmp_path / "par.csv", "--cluster", cluster), sequential)
    out = tmp_path / "shared.csv"
    assert main(["replay", str(cut), "-o", str(out), "--cluster", cluster, "--shared-path"]) == 2
    assert not out.exists()


@pytest.mark.parametrize("extra", [[], ["--all-frames"]], ids=["recorded-frames", "all-frames"])
def test_frames_the_live_run_dropped(dropped, cluster, tmp_path, extra):
    """Frames 3, 6 and 7 have images but no recorded results. By default both replays track the recorded
    frame set; with ``--all-frames`` the parallel one starts a dropped frame from the last recorded result
    before it (the tracker's own search finds the points from there), the sequential one from its own
    previous frame: within 1e-4 px all the same."""
    path, _ = dropped
    sequential = _replay(path, tmp_path / "seq.csv", *extra)
    parallel = _replay(path, tmp_path / "par.csv", "--cluster", cluster, *extra)
    _assert_same(parallel, sequential, verdict=not extra)
    frames = {int(r[0]) for r in parallel[0][1:]}
    assert frames == (set(range(10)) if extra else set(range(10)) - {3, 6, 7})
