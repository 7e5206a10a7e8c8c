"""``livedic bench live`` and ``livedic bench soak``: plumbing and accounting (no timing asserted).

Also the simulator's ``loop=K`` option the soak relies on (render K frames,
cycle them forward and back).
"""

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource, open_synthetic
from livedic.bench.live import HEADER
from livedic.bench.soak import run_soak_benchmark
from livedic.bench.cli import build_parser, main


# --------------------------------------------------------------------------- synthetic loop=K

def test_loop_cycles_rendered_frames_forward_and_back_with_increasing_index():
    source = SyntheticTensileSource("synthetic:tensile?frames=12&loop=4&size=96x96&fps=40&pace=0")
    assert source.frames == 12 and source.rendered_frames == 4
    with source:
        frames = list(source)
    assert [f.index for f in frames] == list(range(12))
    assert [f.timestamp_ns for f in frames] == [i * 25_000_000 for i in range(12)]
    cycle = [0, 1, 2, 3, 2, 1, 0, 1, 2, 3, 2, 1]
    assert [source.rendered_index(i) for i in range(12)] == cycle
    assert len(source._images) == 4
    for frame, j in zip(frames, cycle):
        np.testing.assert_array_equal(frame.image, frames[j].image)
        x, y = np.array([40.0, 50.0]), np.array([30.0, 60.0])
        np.testing.assert_array_equal(frame.metadata["truth"](x, y)[1], source.truth(j, x, y)[1])
    # The schedule spans the rendered frames: the last rendered one is the end of the test.
    assert frames[3].metadata["phase"] == "necking" and frames[6].metadata["phase"] == "elastic"
    assert "cycled forward and back" in source.settings["delivery"] and source.settings["loop"] == 4
    with pytest.raises(ValueError, match="outside"):
        source.truth(12, 1.0, 1.0)


def test_loop_is_off_by_default_and_bounds_memory():
    plain = SyntheticTensileSource("synthetic:tensile?frames=5&size=96x96&pace=0")
    assert plain.rendered_frames == 5 and plain.options["loop"] == 0
    assert [plain.rendered_index(i) for i in range(5)] == [0, 1, 2, 3, 4]
    assert SyntheticTensileSource("synthetic:tensile?frames=5&loop=9&size=96x96").rendered_frames == 5
    # 100,000 frames of 4096x4096 would be 1.6 TB rendered ahead; looping over 3 of them is 48 MB.
    big = open_synthetic("synthetic:tensile?frames=100000&size=4096x4096&loop=3")
    assert big.frames == 100_000 and big.rendered_frames == 3
    with pytest.raises(SourceError, match="loop"):
        open_synthetic("synthetic:tensile?loop=1")
    translate = SyntheticTranslateSource("synthetic:translate?frames=9&loop=3&size=96x96&du=0.5&dv=0&pace=0")
    assert [float(translate.truth(i, 0.0, 0.0)[0]) for i in range(9)] == [0, 0.5, 1, 0.5, 0, 0.5, 1, 0.5, 0]


# --------------------------------------------------------------------------- bench live

def test_cli_wires_bench_live_and_soak():
    parser = build_parser()
    live = parser.parse_args(["bench", "live", "--quick", "--frames", "20", "--fps", "40"])
    assert live.quick and live.frames == 20 and live.fps == 40 and live.handler.__name__ == "_cmd_bench_live"
    soak = parser.parse_args(["bench", "soak", "--frames", "300", "--size", "128", "--keep"])
    assert soak.frames == 300 and soak.size == 128 and soak.keep and soak.handler.__name__ == "_cmd_bench_soak"
    assert parser.parse_args(["bench", "soak"]).frames == 20_000


def test_quick_live_benchmark_prints_its_table_and_the_target_line(capsys):
    assert main(["bench", "live", "--quick", "--frames", "12"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith("livedic bench live: synthetic:tensile 512x512 Mono8")
    assert any(line.startswith("the pipeline by point count and method: 12 frames per case") for line in lines)
    assert any(line.startswith("the main job, everything on") for line in lines)
    assert any(line.startswith(("PASS  target main job at 50 fps", "FAIL  target main job at 50 fps"))
               for line in lines)
    assert any("tracker / IC-GN kernel, p50" in line for line in lines)
    assert "CPU cores" in lines[1] and "load average" in lines[1]
    assert HEADER in lines
    start = lines.index(HEADER) + 2
    rows = lines[start:start + 5]
    labels = ["improved-surface-fit ", "icgn ", "icgn (no-record)", "icgn (search none)", "icgn (unpaced)"]
    for row, label in zip(rows, labels):
        assert label in row and "failed" not in row, row
        assert row.split()[0].isdigit()          # the actual number of points
    target = [line for line in lines if "target 1,000 points IC-GN >= 50 fps" in line]
    assert len(target) == 1 and target[0][:4] in ("PASS", "FAIL") and "quick mode" in target[0]
    assert "improved-wso + IC-GN, recording on" in target[0]
    variant = [line for line in lines if "target 1,000 points IC-GN --search none >= 50 fps" in line]
    assert len(variant) == 1 and variant[0][:4] in ("PASS", "FAIL")
    assert "rendering the simulated frames (before the clock" in out
    assert "what limits it:" in out and "1,000 points IC-GN: tracking p50" in out
    assert "error in" not in out
    # strain + two extensometers in every session (issue 11): its cost per frame, and the target line
    heading = [i for i, line in enumerate(lines) if line.startswith("strain + two extensometers per frame")]
    assert len(heading) == 1 and "axial 245 px" in lines[heading[0]]       # 0.75 x the 327 px ROI at 512x512
    for row, label in zip(lines[heading[0] + 1:heading[0] + 6], labels):
        assert label.strip() in row and "extensometers axial, transverse" in row, row
        p50 = float(row.split("p50")[1].split("ms")[0])
        assert 0.0 < p50 < 1000.0 and "% of tracking" in row
    strain = [line for line in lines if "target strain + two extensometers <= 2 ms per frame at 1,000 points" in line]
    assert len(strain) == 1 and strain[0][:4] in ("PASS", "FAIL") and "quick mode" in strain[0]
    assert "of the tracking time" in strain[0] and "VSG" in strain[0]
    # strain out (issue 13): every session publishes over UDP; one datagram per tracked frame, its latency
    heading = [i for i, line in enumerate(lines) if line.startswith("strain out (--publish udp://127.0.0.1:PORT")]
    assert len(heading) == 1
    for row, label in zip(lines[heading[0] + 1:heading[0] + 6], labels):
        assert label.strip() in row and "result -> sent p50" in row and "read by a thread p50" in row, row
        sent, frames = row.split(" sent")[0].split()[-1].split("/")
        received = int(row.split(" received")[0].split()[-1])
        assert int(sent) == int(frames) == received > 0, row           # one datagram per tracked frame, each read
        sent_latency = row.split("result -> sent ")[1]
        p50, p99 = float(sent_latency.split("p50 ")[1].split()[0]), float(sent_latency.split("p99 ")[1].split()[0])
        assert 0.0 < p50 <= p99, row
    out = [line for line in lines if "target strain-out latency p99 <= 5 ms at 50 fps on loopback" in line]
    assert len(out) == 1 and out[0][:4] in ("PASS", "FAIL") and "quick mode" in out[0]
    assert "NOT one per frame" not in out[0] and "result -> send returned p99" in out[0]


def test_strain_out_receiver_pairs_each_datagram_with_its_result():
    import json
    import socket
    import time

    from livedic.bench.live import StrainOutReceiver, strain_out_numbers
    receiver = StrainOutReceiver()
    port = int(receiver.uri.rsplit(":", 1)[1])
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    done = {}
    for frame in (3, 4, 7):
        done[frame] = time.monotonic_ns()
        sender.sendto(json.dumps({"frame": frame}).encode(), ("127.0.0.1", port))
    sent_ns = time.monotonic_ns()
    sender.close()
    received = receiver.stop()
    assert [frame for frame, _, _ in received] == [3, 4, 7]
    # The kernel's wall-clock stamp moved onto the monotonic clock: between the send and the read
    # (0.5 ms allowed for reading the two clocks apart on a loaded machine).
    for frame, arrival, read in received:
        assert done[frame] <= read
        if receiver.kernel_stamps:
            assert done[frame] - 500_000 <= arrival <= min(read, sent_ns) + 500_000
    numbers = strain_out_numbers({"sent": 3, "failed": 0, "latency_p50_ms": 0.1, "latency_p99_ms": 0.2}, done,
                                 received)
    assert numbers["received"] == numbers["frames"] == numbers["sent"] == 3
    assert numbers["read_p50_ms"] <= numbers["read_p99_ms"]
    assert (numbers["arrival_p99_ms"] is not None) == receiver.kernel_stamps


# --------------------------------------------------------------------------- bench soak

def test_tiny_soak_accounts_for_every_frame(tmp_path):
    lines = []
    result = run_soak_benchmark(frames=300, size=128, fps=100.0, n_points=100, loop=40, directory=str(tmp_path),
                                progress_every=100, warmup_frames=50, log=lines.append)
    assert result["produced"] == 300
    assert result["recorded"] == result["produced"] == result["recorded_written"]
    assert result["tracked"] + result["dropped"] == result["produced"]
    assert result["results_recorded"] == result["tracked"]
    assert result["passed_accounting"] is True
    assert result["rss_start"] > 0 and result["rss_end"] > 0 and np.isfinite(result["rss_growth"])
    text = "\n".join(lines)
    assert "PASS  every produced frame accounted for: recorded 300 == produced 300" in text
    assert ("PASS  RSS growth < 5 %" in text) or ("FAIL  RSS growth < 5 %" in text)
    assert sum("/300 produced" in line for line in lines) == 3          # progress every 100 frames
    assert list(tmp_path.iterdir()) == []                               # recording deleted


def test_soak_command_keeps_the_recording_on_request(tmp_path, capsys):
    code = main(["bench", "soak", "--frames", "40", "--size", "128", "--fps", "200", "--points", "30", "--loop", "10",
                 "--dir", str(tmp_path), "--keep"])
    out = capsys.readouterr().out
    assert "every produced frame accounted for: recorded 40 == produced 40" in out
    kept = list(tmp_path.glob("soak-*.mcap"))
    assert len(kept) == 1 and f"recording kept: {kept[0]}" in out
    from livedic.acquire.recording.reader import inspect_recording
    assert inspect_recording(str(kept[0])).frames == 40
    assert code in (0, 1)          # 1 only if the (timing-dependent) RSS check failed on a 40-frame run
