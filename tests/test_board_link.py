"""The board link (issue 28): the codec, and the simulated board's top level (Verilator, UART
pins on a TCP socket) driven by the real host client (``ik5r solve --solver board``)."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import numpy as np
import pytest

from ik5r.core import link as L
from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import constants, load_config


def test_crc_and_frames_round_trip():
    assert L.crc16(b"123456789") == 0x29B1
    frame = L.encode(L.POSE, 7, range(-3, 11))
    assert frame[0] == L.SYNC and len(frame) == L.frame_bytes(14) == 62
    assert L.crc16(frame[1:]) == 0
    parser = L.Parser()
    # Noise, a frame with a flipped bit, then the good frame: only the good frame comes out.
    broken = bytearray(frame)
    broken[10] ^= 0x04
    (got,) = parser.feed(b"\x00\x13" + bytes(broken) + frame)
    assert (got.kind, got.tag, [got.signed(i) for i in range(14)]) == (L.POSE, 7, list(range(-3, 11)))
    assert parser.dropped >= len(broken)


@pytest.fixture(scope="module")
def k():
    return constants(load_config("q32w"), load_arm(None))


@pytest.fixture(scope="module")
def model(k):
    from ik5r.tools.boardsim import build_model
    from ik5r.tools.softcpu import SoftCpuError

    try:
        return build_model(k)
    except SoftCpuError as exc:
        pytest.fail(str(exc))


class RawLink:
    """The simulated board on a plain socket, for frames the host client would never send."""

    def __init__(self, model, tmp_path):
        from ik5r.tools.boardsim import SIM_BAUD, SIM_CLOCK_HZ, SimulatedBoard

        self.sim = SimulatedBoard(model, SIM_CLOCK_HZ // SIM_BAUD, tmp_path / "stats.txt")
        self.sock = socket.create_connection(("127.0.0.1", self.sim.port))
        self.sock.settimeout(0.2)
        self.parser = L.Parser()

    def frames(self, count: int, wait: float = 20.0) -> list:
        got, deadline = [], time.monotonic() + wait
        while len(got) < count and time.monotonic() < deadline:
            try:
                got += self.parser.feed(self.sock.recv(4096))
            except socket.timeout:
                pass
        return got

    def close(self):
        self.sock.close()
        self.sim.wait()


def _damaged(pose: bytes):
    """(name, bytes, expected error code, the error frame's tag or None, wait for it first)."""
    def body(kind, length, tag, payload=b""):
        data = bytes([kind, length, tag]) + payload
        crc = L.crc16(data)
        return bytes([L.SYNC]) + data + bytes([crc >> 8, crc & 0xFF])

    def flip(index, mask=0x01):
        out = bytearray(pose)
        out[index] ^= mask
        return bytes(out)

    payload = pose[4:-2]
    return [
        ("payload bit", flip(20), L.E_CRC, 0x31, False),
        ("crc byte", flip(61, 0x80), L.E_CRC, 0x31, False),
        ("tag byte, crc not updated", flip(3, 0x02), L.E_CRC, 0x33, False),
        ("joints frame to the board", body(L.JOINTS, 6, 0x41, payload[:24]), L.E_TYPE, 0x41, False),
        ("error frame to the board", body(L.ERROR, 1, 0x42, payload[:4]), L.E_TYPE, 0x42, False),
        ("unknown type 0x7f", body(0x7F, 0, 0x43), L.E_TYPE, 0x43, False),
        ("pose of 13 words", body(L.POSE, 13, 0x44, payload[:52]), L.E_LENGTH, 0x44, False),
        ("pose of 15 words", body(L.POSE, 15, 0x45, payload + payload[:4]), L.E_LENGTH, 0x45, False),
        ("ID request with a payload", body(L.ID, 1, 0x46, payload[:4]), L.E_LENGTH, 0x46, False),
        ("length byte, crc not updated", flip(2, 0x08), L.E_LENGTH, 0x31, False),
        ("truncated pose", pose[:30], L.E_TIMEOUT, 0x31, True),
        ("truncated header", pose[:2], L.E_TIMEOUT, 0, True),
        ("truncated crc", pose[:-1], L.E_TIMEOUT, 0x31, True),
    ]


def test_damaged_frames_answered_and_link_recovers(k, model, tmp_path):
    """Each kind of damaged frame gets an error frame with its code, then a good pose is solved
    bit-exactly (the link resynchronised)."""
    from ik5r.firmware_model import vector
    from ik5r.tools.boardsim import random_poses

    batch = random_poses(k, 1, seed=3)
    words = [*batch.p[0], *batch.a[0], *batch.n[0], *batch.o[0]]
    pose = L.pose_frame(0x31, words, int(batch.q5[0]), batch.roll[0], batch.back[0], batch.down[0])
    q_model, status_model = vector.solve_batch(k, *batch.args())
    cases = _damaged(pose)
    for name, data, *_ in cases:   # the rest of a frame dropped after its header is hunted through
        assert L.SYNC not in data[4:], name
    link = RawLink(model, tmp_path)
    try:
        (boot,) = link.frames(1)
        assert boot.kind == L.ID and boot.tag == 0
        seen = set()
        for name, data, code, tag, wait in cases:
            link.sock.sendall(data)
            if wait:
                (error,) = link.frames(1)
            good = L.pose_frame(0x50, words, int(batch.q5[0]), batch.roll[0], batch.back[0], batch.down[0])
            link.sock.sendall(good)
            got = ([error] if wait else []) + link.frames(1 if wait else 2)
            assert [f.kind for f in got] == [L.ERROR, L.JOINTS], name
            assert (got[0].words[0], got[0].tag) == (code, tag), name
            assert got[1].tag == 0x50, name
            assert [got[1].signed(j) for j in range(5)] == q_model[0].tolist(), name
            assert got[1].words[5] == status_model[0], name
            seen.add(name)
        assert len(seen) >= 10
    finally:
        link.close()


def _poses_csv(k, path, count, seed):
    from ik5r.core import reference

    rng = np.random.default_rng(seed)
    q = rng.uniform(k.arm.lower, k.arm.upper, (count, 5))
    p, n, o, a = reference.fk(k.arm, q)
    header = "px,py,pz,ax,ay,az,nx,ny,nz,ox,oy,oz"
    np.savetxt(path, np.hstack([p, a, n, o]), delimiter=",", header=header, comments="", fmt="%.17g")


def test_solve_on_simulated_board_with_reset(k, model, tmp_path, capsys):
    """``ik5r solve --solver board`` on the simulated board, reset mid-stream: the same CSV as
    the bit-accurate model, --check counts 0 differing words."""
    from ik5r.tools.boardsim import SIM_BAUD, SIM_CLOCK_HZ, SimulatedBoard
    from ik5r.tools.cli import main

    count = 600
    _poses_csv(k, tmp_path / "poses.csv", count, seed=5)
    sim = SimulatedBoard(model, SIM_CLOCK_HZ // SIM_BAUD, tmp_path / "stats.txt", reset_after=62 * 300 + 17)
    try:
        code = main(["solve", str(tmp_path / "poses.csv"), "--solver", "board", "--port", sim.url,
                     "--config", "q32w", "--check", "-o", str(tmp_path / "board.csv")])
        stats = sim.wait()
    finally:
        sim.close()
    err = capsys.readouterr().err
    assert code == 0, err
    assert f"{count} poses, 0 differing words" in err
    assert stats["resets"] == 1
    assert main(["solve", str(tmp_path / "poses.csv"), "--solver", "fixed", "--config", "q32w",
                 "-o", str(tmp_path / "fixed.csv")]) == 0
    assert (tmp_path / "board.csv").read_text() == (tmp_path / "fixed.csv").read_text()


def test_simulated_link_throughput(k, tmp_path, monkeypatch):
    """300 poses: 0 differing words, poses/s within 10% of the line-rate bound (simulated time;
    5,000 poses in the slow set); no scratch folder left behind."""
    import tempfile

    from ik5r.tools.boardsim import run_link

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    record = run_link(k, 300, seed=7)
    assert record["differing_words"] == 0
    assert record["poses_per_s"] >= 0.9 * record["line_poses_per_s"], record
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_simulated_link_5000_poses(k):
    from ik5r.tools.boardsim import run_link

    record = run_link(k, 5000, seed=0)
    assert record["differing_words"] == 0
    assert record["poses_per_s"] >= 0.9 * record["line_poses_per_s"], record


@pytest.mark.slow
def test_compact_core_behind_the_word_adapter(k):
    """The ULX3S-25F's core (SequencedIKCore through WordCore) on the simulated link."""
    from ik5r.tools.boardsim import run_link

    record = run_link(k, 300, seed=11, core="compact")
    assert record["differing_words"] == 0
    assert record["poses_per_s"] >= 0.9 * record["line_poses_per_s"], record


@pytest.mark.parametrize("option", [["--config", "q18"], ["--arm", "longer-5r.toml"]])
def test_board_for_another_config_or_arm_refused(model, tmp_path, capsys, option):
    from ik5r.tools.boardsim import SIM_BAUD, SIM_CLOCK_HZ, SimulatedBoard
    from ik5r.tools.cli import main

    k = constants(load_config("q32w"), load_arm(None))
    _poses_csv(k, tmp_path / "poses.csv", 3, seed=1)
    sim = SimulatedBoard(model, SIM_CLOCK_HZ // SIM_BAUD, tmp_path / "stats.txt")
    try:
        args = option
        if option[0] == "--arm":
            import ik5r
            text = (Path(ik5r.__file__).parent / "data" / "arms" / "hu-5r.toml").read_text()
            (tmp_path / option[1]).write_text(text.replace("a = 9.5", "a = 9.6", 1))
            args = ["--config", "q32w", "--arm", str(tmp_path / option[1])]
        code = main(["solve", str(tmp_path / "poses.csv"), "--solver", "board", "--port", sim.url, *args])
    finally:
        sim.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "board built for another " + ("arm" if option[0] == "--arm" else "config") in err[0]
