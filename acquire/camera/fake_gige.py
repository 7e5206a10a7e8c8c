"""GigE Vision fake cameras serving OUR images, for tests and the live benchmark, found by discovery like a
real GigE camera.

* :class:`GigEFakeCamera` — an ``Aravis.GvFakeCamera`` (GigE Vision simulator)
  in a child Python process on 127.0.0.1 (GVCP port 3956, loopback only).
  ``kill()`` simulates a lost camera. ``image_fn(k)`` returns frame k's image
  (uint8 or uint16, 2-D); ``k`` counts the frames since the simulator started or
  ``reset_count()``, so it equals ``Frame.index`` after ``reset_count()``.
* :class:`ArvFakeGvCamera` — Aravis's own simulator program, as a user runs it.

Run a GigE fake camera by hand (Ctrl-C stops it)::

    python -m livedic.acquire.camera.fake_gige --size 1024x1024 --step 1,-1
    livedic cameras        # lists Aravis-Fake-LIVEDIC0 at 127.0.0.1
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import errno
import fcntl
import json
import os
import pickle
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from typing import IO, Any, Literal, TypeVar, cast

from livedic.acquire.base import SourceError
from livedic.acquire.camera import aravis as _aravis
from livedic.acquire.camera.aravis_discovery import SCHEME, list_cameras, load_aravis
from livedic.acquire.camera.fake_motion import FillPattern, SpeckleMotion

__all__ = ["ARV_FAKE_GV_CAMERA", "ArvFakeGvCamera", "GVCP_PORT", "GigEFakeCamera"]

GVCP_PORT = 3956


# --------------------------------------------------------------------------- #
# GigE Vision fake camera in a child process
# --------------------------------------------------------------------------- #

def _serve_gige_child() -> int:
    """Child process body (``python -m acquire.camera.fake_gige --child``).

    stdin: 8-byte length + pickle of ``(image_fn, address, serial, genicam)``, then command
    lines (``stats``, ``reset``, ``stop``); EOF (the parent died) also stops. stdout: one
    JSON line per answer, the first being ``{"ready": ...}`` or ``{"error": ...}``.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    stdin, stdout = sys.stdin.buffer, sys.stdout

    def answer(**message) -> None:
        stdout.write(json.dumps(message) + "\n")
        stdout.flush()

    camera = pattern = None
    try:
        size = int.from_bytes(stdin.read(8), "little")
        image_fn, address, serial, genicam = pickle.loads(stdin.read(size))
        Aravis, _ = load_aravis()
        camera = Aravis.GvFakeCamera.new_full(address, serial, genicam)
        if camera is None or not camera.is_running():
            answer(error=f"Aravis.GvFakeCamera did not start on {address}:{GVCP_PORT}")
            return 1
        pattern = FillPattern(image_fn)
        pattern.install(camera.get_fake_camera())
        answer(ready=True, pid=os.getpid())
        for line in stdin:
            command = line.strip()
            if command == b"stop":
                break
            if command == b"stats":
                answer(frames_served=pattern.frames_served, errors=pattern.errors, last_error=pattern.last_error)
            if command == b"reset":
                pattern.frames_served = 0
                answer(reset=True)
    except BaseException as error:  # noqa: BLE001 - reported to the parent
        with contextlib.suppress(Exception):
            answer(error=f"{type(error).__name__}: {error}")
        return 1
    finally:
        del camera   # stops the simulator thread before the callback goes
        del pattern
    return 0


def _port_in_use(address, port):
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.bind((address, port))
    except OSError as error:
        return error.errno == errno.EADDRINUSE
    finally:
        probe.close()
    return False


class _GvcpAddressLock:
    """Who may run a GigE simulator on ``address``: one at a time on this machine (GVCP port 3956).

    A lock file in the temp folder serialises livedic's simulators (waits up to ``timeout_s``); a port probe
    catches one started by other means. ``acquire()`` also waits for the teardown of a camera lost earlier
    in this process (its GVCP writes time out for ~7 s) so that they cannot reach the new simulator.
    """

    def __init__(self, address, timeout_s) -> None:
        self.address = address
        self.timeout_s = timeout_s
        self._file = None

    def acquire(self):
        path = os.path.join(tempfile.gettempdir(), f"livedic-fake-gige-{self.address}.lock")
        lock_file = open(path, "a+")
        deadline = time.monotonic() + self.timeout_s
        while True:
            try:
                fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    lock_file.close()
                    raise SourceError(f"another livedic fake GigE camera holds {self.address}:{GVCP_PORT} "
                                      f"(lock {path}) for more than {self.timeout_s:g} s") from None
                time.sleep(0.1)
        self._file = lock_file
        try:
            for thread in list(_aravis._TEARDOWN_THREADS):
                thread.join(timeout=15)
            if _port_in_use(self.address, GVCP_PORT):
                raise SourceError(f"UDP {self.address}:{GVCP_PORT} is already in use (another GigE Vision "
                                  "camera simulator, e.g. arv-fake-gv-camera-0.8?): stop it first")
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        if self._file is not None:
            try:
                fcntl.flock(self._file, fcntl.LOCK_UN)
            finally:
                self._file.close()
                self._file = None


def _stop_process(process, polite) -> None:
    """End a simulator process: ``polite()`` (may be None), then SIGTERM, then SIGKILL; waits for it."""
    steps = ([polite] if polite is not None else []) + [process.terminate, process.kill]
    for step in steps:
        if process.poll() is not None:
            break
        with contextlib.suppress(OSError, ValueError):
            step()
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=5)
    for pipe in (process.stdin, process.stdout, process.stderr):
        if pipe is not None:
            with contextlib.suppress(OSError, ValueError):
                pipe.close()


def _load_prctl():
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


_PRCTL = _load_prctl()           # looked up here: the forked child only calls it
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """``preexec_fn``: the kernel kills the child when the thread that started it dies (a killed test run
    leaves no simulator holding port 3956). Linux only; elsewhere a no-op."""
    if _PRCTL is not None:
        _PRCTL(_PR_SET_PDEATHSIG, int(signal.SIGKILL))


_S = TypeVar("_S", bound="_Simulator")


class _Simulator:
    """A GigE simulator process (``serial``, ``_process``): ``with simulator:`` starts it and stops it;
    dropping it stops it too (the address is freed)."""

    serial: str
    _process: subprocess.Popen[bytes] | None

    def start(self: _S) -> _S:
        raise NotImplementedError        # each simulator starts its own process

    def stop(self) -> None:
        raise NotImplementedError

    @property
    def device_id(self) -> str:
        """The Aravis id discovery lists it by."""
        return f"Aravis-Fake-{self.serial}"

    @property
    def alive(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def __enter__(self: _S) -> _S:
        return self.start()

    def __exit__(self, *exc: object) -> Literal[False]:
        self.stop()
        return False

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.stop()


class GigEFakeCamera(_Simulator):
    """A GigE Vision fake camera on 127.0.0.1, in a child process, serving ``image_fn(k)``.

    Only one can listen on an address (GVCP port 3956): a lock file in the
    temp folder serialises users on this machine (waits up to ``lock_timeout_s``),
    and a port probe catches a simulator started by other means
    (``arv-fake-gv-camera-0.8``).

    Parameters
    ----------
    image_fn : picklable callable ``k -> ndarray``
        Defaults to ``SpeckleMotion()``. Pickled to a child Python
        (``python -m acquire.camera.fake_gige --child``), so it must be picklable and
        importable there (a module-level function or an object such as SpeckleMotion).
    serial : str
        Serial number; the Aravis device id is ``"Aravis-Fake-" + serial``.
    address : str
        IPv4 address of a local interface to listen on (loopback by default).
    genicam : str, optional
        A GenICam XML file to serve instead of Aravis's (e.g. :func:`extended_genicam_xml`).

    Notes
    -----
    Loopback throughput depends on the packet size: livedic opens a loopback camera with
    9000-byte packets unless ``packet_size`` says otherwise (the camera's default is 1400).
    """

    def __init__(self, image_fn: Callable[[int], Any] | None = None, *, serial: str = "LIVEDIC0",
                 address: str = "127.0.0.1", genicam: str | os.PathLike[str] | None = None,
                 start_timeout_s: float = 20.0, lock_timeout_s: float = 60.0) -> None:
        self.image_fn = image_fn if image_fn is not None else SpeckleMotion()
        self.serial = serial
        self.address = address
        self.genicam = None if genicam is None else str(genicam)
        self.start_timeout_s = start_timeout_s
        self.lock_timeout_s = lock_timeout_s
        self._process = None
        self._lock = _GvcpAddressLock(address, lock_timeout_s)

    @property
    def uri(self) -> str:
        """``aravis:<address>``: opening by address skips matching the discovered list."""
        return f"{SCHEME}:{self.address}"

    @property
    def pid(self) -> int | None:
        return self._process.pid if self._process is not None else None

    def start(self):
        """Start the child and wait until the camera listens; returns self."""
        if self._process is not None:
            return self
        self._lock.acquire()
        try:
            payload = pickle.dumps((self.image_fn, self.address, self.serial, self.genicam))
            root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
            env = dict(os.environ)
            env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
            self._process = subprocess.Popen(
                [sys.executable, "-m", "livedic.acquire.camera.fake_gige", "--child"], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, cwd=root, env=env, start_new_session=True, preexec_fn=_die_with_parent)
            self._process.stdin.write(len(payload).to_bytes(8, "little") + payload)
            self._process.stdin.flush()
            message = self._read_answer(self.start_timeout_s)
            if message is None:
                raise SourceError(f"fake GigE camera did not start within {self.start_timeout_s:g} s")
            if "ready" not in message:
                raise SourceError(f"fake GigE camera failed to start: {message.get('error', message)}")
        except BaseException:
            self.stop()
            raise
        return self

    def _read_answer(self, timeout_s):
        stdout = self._process.stdout
        ready, _, _ = select.select([stdout], [], [], timeout_s)
        if not ready:
            return None
        line = stdout.readline()
        if not line:
            return {"error": f"child exited (code {self._process.poll()})"}
        return json.loads(line)

    def served(self):
        """``{"frames_served", "errors", "last_error"}`` from the child, or ``None`` if it is gone."""
        if not self.alive:
            return None
        try:
            self._process.stdin.write(b"stats\n")
            self._process.stdin.flush()
            return self._read_answer(2.0)
        except (OSError, ValueError):
            return None

    def reset_count(self):
        """Restart ``k`` at 0: call it before opening a stream so ``Frame.index`` equals ``k``."""
        if not self.alive:
            raise SourceError("the fake GigE camera is not running")
        self._process.stdin.write(b"reset\n")
        self._process.stdin.flush()
        if self._read_answer(2.0) != {"reset": True}:
            raise SourceError("the fake GigE camera did not acknowledge reset")

    def kill(self) -> None:
        """SIGKILL the child: the camera vanishes mid-stream, like a pulled cable."""
        process = self._process
        if self.alive and process is not None:       # alive: it is there and running
            process.kill()
            process.wait(timeout=5)

    def stop(self) -> None:
        """Stop the child (politely, then by force) and free the address."""
        process, self._process = self._process, None
        try:
            if process is not None:
                stdin = cast(IO[bytes], process.stdin)        # the child was started with stdin=PIPE

                def ask() -> None:
                    stdin.write(b"stop\n")
                    stdin.flush()
                _stop_process(process, ask)
        finally:
            self._lock.release()


# --------------------------------------------------------------------------- #
# Aravis's own GigE Vision simulator (arv-fake-gv-camera-0.8)
# --------------------------------------------------------------------------- #

ARV_FAKE_GV_CAMERA = "arv-fake-gv-camera-0.8"


class ArvFakeGvCamera(_Simulator):
    """Aravis's GigE Vision simulator program, ``arv-fake-gv-camera-0.8 -i ADDRESS -s SERIAL``, as a user runs it.

    Its images are Aravis's own (a diagonal ramp), not ours; it is what a user tries first, and the
    camera livedic must open exactly as ``livedic cameras`` lists it. ``start()`` returns once GigE
    discovery finds the camera (not after a sleep); ``stop()`` ends it (SIGTERM, then SIGKILL) and the
    kernel kills it if this process dies. One simulator per address: it shares
    :class:`GigEFakeCamera`'s lock.

    Parameters
    ----------
    serial : str
        ``-s``: the Aravis id is ``"Aravis-Fake-" + serial``.
    address : str
        ``-i``: the address to listen on (loopback by default).
    genicam : str, optional
        ``-g``: a GenICam XML file to serve instead of the built-in one (its registers must be the fake's).
    program : str
        The simulator executable (looked up on PATH).

    Raises
    ------
    SourceError
        The program is missing, the address is taken, or discovery does not find it within
        ``start_timeout_s`` (its stderr is quoted).
    """

    def __init__(self, *, serial: str = "GV01", address: str = "127.0.0.1",
                 genicam: str | os.PathLike[str] | None = None, program: str = ARV_FAKE_GV_CAMERA,
                 start_timeout_s: float = 20.0, lock_timeout_s: float = 60.0) -> None:
        self.serial = serial
        self.address = address
        self.genicam = genicam
        self.program = program
        self.start_timeout_s = start_timeout_s
        self._lock = _GvcpAddressLock(address, lock_timeout_s)
        self._process = None
        self._log: IO[bytes] | None = None
        self.listing: dict[str, Any] | None = None     # the list_cameras() entry that found it

    def start(self):
        """Run the program and wait until GigE discovery lists it; returns self."""
        import shutil
        if self._process is not None:
            return self
        executable = shutil.which(self.program)
        if executable is None:
            raise SourceError(f"{self.program} is not installed (Debian package aravis-tools; "
                              "scripts/install_system.sh installs it)")
        self._lock.acquire()
        try:
            command = [executable, "-i", self.address, "-s", self.serial]
            if self.genicam:
                command += ["-g", str(self.genicam)]
            self._log = tempfile.TemporaryFile()
            self._process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=self._log,
                                             stderr=subprocess.STDOUT, start_new_session=True,
                                             preexec_fn=_die_with_parent)
            self.listing = self._wait_for_discovery()
        except BaseException:
            self.stop()
            raise
        return self

    def _wait_for_discovery(self):
        deadline = time.monotonic() + self.start_timeout_s
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise SourceError(f"{self.program} exited with code {self._process.returncode}: {self.output()}")
            # each discovery listens for answers until 1 s of silence: this is the wait
            found = [c for c in list_cameras() if c["id"] == self.device_id]
            if found and found[0]["address"] == self.address:
                return found[0]
        raise SourceError(f"GigE discovery did not find {self.device_id} on {self.address} within "
                          f"{self.start_timeout_s:g} s; {self.program} said: {self.output() or 'nothing'}")

    def output(self) -> str:
        """What the program printed (stdout and stderr), for error messages."""
        if self._log is None:
            return ""
        self._log.seek(0)
        return self._log.read().decode(errors="replace").strip()[-2000:]

    def stop(self) -> None:
        """End the program and free the address."""
        process, self._process = self._process, None
        try:
            if process is not None:
                _stop_process(process, None)
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None
            self._lock.release()


# --------------------------------------------------------------------------- #
# Command line: run a GigE fake camera until Ctrl-C
# --------------------------------------------------------------------------- #

def _pair(text: str) -> tuple[int, ...]:
    parts = text.lower().replace("x", ",").split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected two integers, got {text!r}")
    return tuple(int(p) for p in parts)


def main(argv: Sequence[str] | None = None) -> int:
    if (sys.argv[1:] if argv is None else argv) == ["--child"]:
        return _serve_gige_child()
    parser = argparse.ArgumentParser(prog="python -m livedic.acquire.camera.fake_gige",
                                     description="Run a GigE Vision fake camera on 127.0.0.1 serving a "
                                                 "moving speckle pattern (Ctrl-C stops it).")
    parser.add_argument("--size", type=_pair, default=(512, 512), metavar="WxH")
    parser.add_argument("--step", type=_pair, default=(1, -1), metavar="DU,DV",
                        help="integer displacement per frame (default 1,-1)")
    parser.add_argument("--max-displacement", type=int, default=32)
    parser.add_argument("--bit-depth", type=int, choices=(8, 16), default=8)
    parser.add_argument("--serial", default="LIVEDIC0")
    args = parser.parse_args(argv)
    width, height = args.size
    motion = SpeckleMotion((height, width), step=args.step, max_displacement=args.max_displacement,
                           bit_depth=args.bit_depth)
    with GigEFakeCamera(motion, serial=args.serial) as camera:
        print(f"fake GigE camera {camera.device_id} on {camera.address}: open "
              f"'{camera.uri}?roi=0,0,{width},{height}&pixel_format=Mono{8 if args.bit_depth == 8 else 16}"
              f"&packet_size=9000' (Ctrl-C stops)", flush=True)
        try:
            while camera.alive:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
