"""The host end of the board link (docs/protocol.md): poses out, joints back, over pyserial.

:class:`BoardClient` opens a port (a device such as ``/dev/ttyUSB1`` or any pyserial URL, e.g.
``socket://127.0.0.1:N`` for the simulated board), reads the board's ID frame and refuses a
board built for another config or arm (:class:`~ik5r.core.errors.InputError`, one line). Then
:meth:`BoardClient.solve` streams poses with up to the board's credit count in flight. A pose
is sent again when the board answers its frame with an error frame, when the board resets (an
ID frame it did not ask for) and when no frame came for ``timeout`` seconds; tags are handed
out in turn over 0..255, so an answer to a pose sent twice (the first copy was only late)
finds its tag retired and is ignored.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ik5r.core import link as L
from ik5r.core.errors import InputError

DEFAULT_BAUD = 3_000_000
#: The tag of the host's ID requests (the ID frame a board sends after reset has tag 0).
ID_REQUEST_TAG = 0xC3


@dataclass
class LinkStats:
    poses: int = 0
    error_frames: dict = field(default_factory=dict)   # code -> count
    resent: int = 0
    board_resets: int = 0
    timeouts: int = 0
    seconds: float = 0.0


def open_port(port: str, baud: int):
    try:
        import serial
    except ImportError:
        raise InputError("--port", "needs pyserial: pip install pyserial") from None
    try:
        return serial.serial_for_url(port, baudrate=baud, timeout=0.02)
    except (serial.SerialException, ValueError) as exc:
        raise InputError(port, f"cannot open: {exc}") from None


class BoardClient:
    """A board on ``port`` (see the module docstring); ``expect``: the constants it must match."""

    def __init__(self, port: str, *, baud: int = DEFAULT_BAUD, timeout: float = 2.0):
        self.port_name, self.timeout = port, timeout
        self.port = open_port(port, baud)
        self.parser = L.Parser()
        self.stats = LinkStats()
        self.id = None
        self._tag = 0

    def close(self):
        self.port.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _frames(self) -> list:
        data = self.port.read(max(1, self.port.in_waiting))
        return self.parser.feed(data) if data else []

    def identify(self, wait: float = 5.0) -> dict:
        """The board's ID frame (asked for until it comes, for ``wait`` seconds)."""
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            self.port.write(L.encode(L.ID, ID_REQUEST_TAG))
            until = min(deadline, time.monotonic() + 0.5)
            while time.monotonic() < until:
                for frame in self._frames():
                    if frame.kind == L.ID and frame.tag == ID_REQUEST_TAG and len(frame.words) == len(L.ID_FIELDS):
                        self.id = dict(zip(L.ID_FIELDS, frame.words))
                        return self.id
        raise InputError(self.port_name, f"no ID frame from the board within {wait:g} s")

    def check(self, constants) -> None:
        """InputError unless the board was built for ``constants``' config and arm."""
        ident = self.id or self.identify()
        if ident["protocol"] != L.PROTOCOL_VERSION:
            raise InputError(self.port_name, f"board speaks protocol {ident['protocol']}, this host {L.PROTOCOL_VERSION}")
        for what, mine in (("config", L.config_hash(constants)), ("arm", L.arm_hash(constants))):
            if ident[f"{what}_hash"] != mine:
                raise InputError(self.port_name, f"board built for another {what} (hash {ident[f'{what}_hash']:08x}, "
                                                 f"this {what} {mine:08x}): rebuild it with ik5r board or pass its --{what}")

    def _next_tag(self, busy) -> int:
        while self._tag in busy:
            self._tag = (self._tag + 1) % 256
        tag, self._tag = self._tag, (self._tag + 1) % 256
        return tag

    def solve(self, frames: list[bytes], progress=None) -> list:
        """Send each pose frame body (built with tag 0; see :func:`pose_frames`) and return the
        joints frames in the same order."""
        credits = max(1, int((self.id or self.identify())["credits"]))
        answers = [None] * len(frames)
        flight: dict[int, int] = {}        # tag -> pose index
        todo = deque(range(len(frames)))
        done, last_frame, start = 0, time.monotonic(), time.monotonic()
        while done < len(frames):
            out = bytearray()
            while todo and len(flight) < credits:
                index = todo.popleft()
                tag = self._next_tag(flight)
                flight[tag] = index
                out += _retag(frames[index], tag)
            if out:
                self.port.write(bytes(out))
            got = self._frames()
            if got:
                last_frame = time.monotonic()
            for frame in got:
                done += self._take(frame, flight, todo, answers, progress)
            if not got and flight and time.monotonic() - last_frame > self.timeout:
                self.stats.timeouts += 1
                self._resend_all(flight, todo)
                last_frame = time.monotonic()
        self.stats.poses += len(frames)
        self.stats.seconds += time.monotonic() - start
        return answers

    def _resend_all(self, flight, todo):
        self.stats.resent += len(flight)
        todo.extendleft(sorted(flight.values(), reverse=True))
        flight.clear()

    def _take(self, frame, flight, todo, answers, progress) -> int:
        if frame.kind == L.JOINTS and frame.tag in flight and len(frame.words) == L.JOINT_WORDS:
            answers[flight.pop(frame.tag)] = frame
            if progress is not None:
                progress(1)
            return 1
        if frame.kind == L.ERROR:
            code = frame.words[0] if frame.words else 0
            self.stats.error_frames[code] = self.stats.error_frames.get(code, 0) + 1
            if frame.tag in flight:
                self.stats.resent += 1
                todo.appendleft(flight.pop(frame.tag))
        elif frame.kind == L.ID and frame.tag != ID_REQUEST_TAG:  # the board reset: what was in flight is lost
            self.stats.board_resets += 1
            self._resend_all(flight, todo)
        return 0


def _retag(frame: bytes, tag: int) -> bytes:
    body = bytearray(frame[1:-2])
    body[2] = tag
    crc = L.crc16(bytes(body))
    return bytes([L.SYNC]) + bytes(body) + bytes([crc >> 8, crc & 0xFF])


def pose_frames(p, a, n, o, roll, back, down, q5) -> list[bytes]:
    """Pose frames (tag 0) of ``PoseBatch.args()``."""
    return [L.pose_frame(0, [*p[i], *a[i], *n[i], *o[i]], int(q5[i]), roll[i], back[i], down[i])
            for i in range(len(p))]


def joints(answers) -> tuple[np.ndarray, np.ndarray]:
    """(q words (N, 5), status (N,)) of joints frames."""
    q = np.array([[f.signed(j) for j in range(5)] for f in answers], dtype=np.int64).reshape(-1, 5)
    status = np.array([f.words[5] for f in answers], dtype=np.int64)
    return q, status


def board_solver(port: str, constants, *, baud: int = DEFAULT_BAUD, show_progress: bool | None = None):
    """``solve_batch`` of the fixed-point solvers running on the board at ``port`` (checked first)."""
    client = BoardClient(port, baud=baud)
    client.check(constants)
    show = sys.stderr.isatty() if show_progress is None else show_progress

    def solve_batch(*args):
        frames = pose_frames(*(np.asarray(v) for v in args))
        if not show:
            return joints(client.solve(frames))
        from tqdm import tqdm
        with tqdm(total=len(frames), unit="pose", file=sys.stderr, leave=False) as bar:
            return joints(client.solve(frames, progress=bar.update))
    solve_batch.client = client
    return solve_batch
