"""What every frame source yields and how it is opened and closed."""

from abc import ABC, abstractmethod
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Literal, TypeVar

import numpy as np


class SourceError(RuntimeError):
    """A source could not be opened or stopped delivering frames; the message says what to do."""


class NoFirstFrame(SourceError):
    """A source opened but delivered no frame within its time limit: not lost, it never started.

    ``checks`` lists what to look at (a camera: its trigger, the GigE packet size and
    firewall, another program holding it), each a short phrase; the message has them too.
    """

    def __init__(self, message: str, *, checks: Iterable[str] = ()) -> None:
        super().__init__(message)
        self.checks = tuple(checks)


class SourceLost(SourceError):
    """A source that had delivered frames failed mid-session (``livedic run`` exits 3, recording kept)."""


@dataclass(frozen=True)
class Frame:
    """One image from a source.

    index : int            frame number from the source, 0-based (gaps mean frames lost upstream)
    timestamp_ns : int     acquisition time in nanoseconds (camera clock when it has one)
    image : ndarray        2-D uint8 or uint16 grey image, shape (H, W)
    pixel_format : str     "Mono8", "Mono10", "Mono12" or "Mono16" (10 to 16 bits are stored in uint16,
                           least significant bit first: a 12-bit image holds 0..4095)
    metadata : dict        per-frame extras, e.g. "truth_u"/"truth_v" for synthetic sources
    right : Frame or None  a stereo pair travels as its left frame with the right camera's frame of the same
                           trigger here (``acquire.stereo``); None for one camera
    """
    index: int
    timestamp_ns: int
    image: np.ndarray
    pixel_format: str
    metadata: dict = field(default_factory=dict)
    right: "Frame | None" = None


_Source = TypeVar("_Source", bound="FrameSource")


class FrameSource(ABC):

    """A context manager that yields ``Frame`` objects.

    ``with open_source(uri) as source: for frame in source: ...``. Iteration ends
    when the source is exhausted (files) or closed; a lost camera raises
    ``SourceError``. ``settings`` describes the source for session metadata.
    """

    uri: str = ""

    @abstractmethod
    def __iter__(self) -> Iterator[Frame]:
        ...

    @property
    def live(self) -> bool:
        """Frames come at the pace of a real clock (a camera; a file or the simulator delivered at its frame
        rate): the time from a frame's arrival to its result is a latency, and a slow consumer must drop
        frames. False (files, unpaced): frames come as fast as they are taken, so only the processing time
        and the rate achieved mean something."""
        return False

    @property
    def settings(self) -> dict:
        return {}

    def close(self) -> None:
        pass

    def __enter__(self: _Source) -> _Source:
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close()
        return False
