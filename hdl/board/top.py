"""The board's top level: UART in, frame decoder, IK core, frame encoder, UART out, two LEDs.

:class:`BoardLink` is independent of any board (ports ``rx``, ``tx`` and the LEDs): the Verilator
harness simulates exactly it, and :mod:`ik5r.tools.board` puts it on an ``amaranth-boards``
platform. Its ID frame (:mod:`ik5r.core.link`) names the config and arm the core was built for.
"""

from __future__ import annotations

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from ik5r.core import link as L
from ik5r.core.fxconfig import Constants
from ik5r.core.modes import BOARD_CORES, BoardCore, CoreArch, Dsp

from .decoder import FrameDecoder
from .encoder import FrameEncoder
from .uart import UartRx, UartTx, divider

__all__ = ["BoardLink", "id_words", "credits"]

TAG_BITS = 8
#: Bit times of silence inside a frame before the decoder gives up on it (a truncated frame).
TIMEOUT_BITS = 256
#: LEDs stay lit this many clocks (2^n) after the activity or error that lit them.
LED_STRETCH_BITS = 20


def credits(fifo_bytes: int) -> int:
    """Poses the host may have in flight: as many pose frames as the receive FIFO holds."""
    return fifo_bytes // L.frame_bytes(L.POSE_WORDS)


def id_words(constants: Constants, core: str, clock_hz: int, baud: int, fifo_bytes: int) -> list[int]:
    from ik5r import __version__

    return [L.PROTOCOL_VERSION, L.version_word(__version__), L.config_hash(constants), L.arm_hash(constants),
            L.CORES[core], clock_hz, baud, credits(fifo_bytes)]


def _core(constants: Constants, core: str, dsp: str):
    """The IK core with 32-bit word streams (``SerialIK`` takes them as 32-bit beats); ``dsp``
    maps the pipelined core's multipliers and adders (the others multiply sequentially)."""
    if core == BoardCore.SERIAL:
        from ..sequenced.serial import SerialIK
        return SerialIK(constants=constants, tag_width=TAG_BITS, beat_bits=32)
    from .adapt import WordCore
    if core == BoardCore.COMPACT:
        from ..sequenced.engine import SequencedIKCore
        return WordCore(core=SequencedIKCore(constants=constants, tag_width=TAG_BITS))
    from ..pipelined.core import IKCore
    return WordCore(core=IKCore(constants=constants, arch=CoreArch.PIPELINED, tag_width=TAG_BITS, dsp=dsp))


class BoardLink(wiring.Component):
    """The IK core on a framed UART link (docs/protocol.md).

    Function: bytes on ``rx`` go through a ``fifo_bytes`` receive FIFO to the frame decoder,
    pose words to the IK core ``core`` (serial, compact or pipelined), its results and the
    decoder's replies to the frame encoder and out on ``tx``; an ID frame leaves after reset.
    ``led_activity`` is lit while bytes come or go (stretched), ``led_error`` after an error
    frame or a UART framing error. Formats: 8N1 at ``baud`` with a ``clock_hz`` clock.
    ``dsp`` (:class:`~ik5r.core.modes.Dsp`) maps a pipelined core's multipliers: ``"ecp5"`` on an
    ECP5 board, where the generic products would each take a DSP, narrow ones included.
    Latency: the core's plus the frames' time on the line. Throughput: the line's (a pose frame
    is 62 bytes, a joints frame 30) unless the core is slower; the ID frame's credits bound the
    poses in flight so that the FIFO never overflows.
    """

    def __init__(self, *, constants: Constants, core: str, clock_hz: int, baud: int, fifo_bytes: int = 512,
                 dsp: str = Dsp.GENERIC):
        if core not in BOARD_CORES:
            raise ValueError(f"core must be one of {BOARD_CORES}, got {core!r}")
        if isinstance(fifo_bytes, bool) or not isinstance(fifo_bytes, int) or credits(fifo_bytes) < 1:
            raise ValueError(f"fifo_bytes must hold a pose frame, got {fifo_bytes!r}")
        self.constants, self.core_name, self.clock_hz, self.baud = constants, core, clock_hz, baud
        self.fifo_bytes = fifo_bytes
        divider(clock_hz, baud)   # a ValueError before any component is made
        self.dsp = Dsp(dsp)
        self.core = _core(constants, core, self.dsp)
        inner = getattr(self.core, "core", self.core)
        #: Clocks per pose of the IK core.
        self.cycles_per_result = inner.cycles_per_result
        self.rx_uart = UartRx(clock_hz=clock_hz, baud=baud)
        self.tx_uart = UartTx(clock_hz=clock_hz, baud=baud)
        self.id = id_words(constants, core, clock_hz, baud, fifo_bytes)
        super().__init__({"rx": In(1, init=1), "tx": Out(1, init=1),
                          "led_activity": Out(1), "led_error": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.rx = rx = self.rx_uart
        m.submodules.tx = tx = self.tx_uart
        m.submodules.fifo = fifo = SyncFIFOBuffered(width=8, depth=self.fifo_bytes)
        timeout = max(16, TIMEOUT_BITS * -(-self.clock_hz // self.baud))
        m.submodules.decoder = decoder = FrameDecoder(timeout=timeout)
        m.submodules.core = core = self.core
        m.submodules.encoder = encoder = FrameEncoder(word_bits=self.constants.cfg.width, id_words=self.id,
                                                      status_bits=self.constants.status_width)
        m.d.comb += [rx.rx.eq(self.rx), self.tx.eq(tx.tx)]
        wiring.connect(m, rx.o, fifo.w_stream)
        wiring.connect(m, fifo.r_stream, decoder.i)
        wiring.connect(m, decoder.o, core.i)
        wiring.connect(m, core.o, encoder.results)
        wiring.connect(m, decoder.reply, encoder.reply)
        wiring.connect(m, encoder.o, tx.i)
        m.d.comb += decoder.overflow.eq(rx.overrun)
        self._leds(m, rx.busy | tx.busy, encoder.sent_error | rx.framing)
        return m

    def _leds(self, m, activity, error):
        for led, event in ((self.led_activity, activity), (self.led_error, error)):
            left = Signal(LED_STRETCH_BITS)
            with m.If(event):
                m.d.sync += left.eq(-1)
            with m.Elif(left != 0):
                m.d.sync += left.eq(left - 1)
            m.d.comb += led.eq(left != 0)
