"""Cross-compile the C solver for a 32-bit RISC-V soft CPU (bare metal, RV32IM or RV32I).

``ik5r.c`` + the generated ``ik5r_config.h`` + the harness ``rv32_main.c`` / ``rv32_start.S`` are
built with Debian's ``riscv64-unknown-elf-gcc`` and picolibc's headers (``-march=<isa>
-mabi=ilp32 -O2``, ``-Wall -Wextra -Werror -std=c99 -pedantic``), linked by ``rv32.ld`` for the RAM
of :class:`ik5r.hdl.soc.system.SoC`. RV32I has no multiply instruction: gcc calls libgcc's
``__mulsi3`` / ``__muldi3`` (software multiply), which is the point of that build.

Builds are cached like the host C (:func:`ik5r.core.cbuild.cache_root`), keyed by the
sources, the header, the compiler's version and every flag. A missing cross compiler or a failed
build raises :class:`Rv32BuildError` with a one-line message.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ik5r.core.fxconfig import Constants

from .codegen import HEADER_NAME, generate_header
from ik5r.core.cbuild import cache_root
from ik5r.core.regmap_out import HEADER_NAME as REGS_HEADER
from ik5r.core.regmap_out import c_header as regs_header

from .csolver import SOURCE_DIR

ISAS = ("rv32im", "rv32i")
PREFIX = "riscv64-unknown-elf-"
SOURCES = ("ik5r.c", "ik5r.h", "rv32_main.c", "rv32_start.S", "rv32.ld")
#: The firmware of the IK peripheral (both paths on every pose): the driver and its harness.
#: The driver is linked right after the harness's main, before the solver: the timed loop and
#: the driver then sit together in the 4 KiB instruction cache (with the q32w solver between
#: them they evicted each other: about 60 cycles a call).
PERIPH_SOURCES = ("ik5r_hw.c", "ik5r_hw.h", "ik5r.c", "ik5r.h", "rv32_periph_main.c",
                  "rv32_periph_start.S", "rv32.ld")
CFLAGS = ("-mabi=ilp32", "-O2", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror",
          "-ffreestanding", "-ffunction-sections", "-fdata-sections", "-DIK5R_NO_BATCH_API")
#: Words of one pose in the job area and of one result (rv32_main.c).
POSE_WORDS = 14
RESULT_WORDS = 6
#: Words of one result of the peripheral harness: q_a[5] status of the blocking hardware call, of
#: the interrupt path, of the software.
PERIPH_RESULT_WORDS = 18
JOB_HEADER_WORDS = 2
STACK_BYTES = 2048
#: Packages that provide the toolchain on Debian / Ubuntu.
APT_PACKAGES = "gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf"


class Rv32BuildError(RuntimeError):
    """The cross compiler is missing or the firmware did not build (one-line message)."""


@dataclass(frozen=True)
class Firmware:
    """A linked firmware: its RAM image and where the job area starts."""

    isa: str
    elf: Path
    image: tuple[int, ...]       # little-endian 32-bit words from address 0
    job_word: int                # word index of ik5r_job
    ram_words: int
    code_bytes: int              # .text (solver, harness, libgcc helpers)
    data_bytes: int              # .rodata + .data + .sdata + .bss
    stack_bytes: int
    result_words: int = RESULT_WORDS

    def job_capacity(self) -> int:
        """The most poses one job can hold."""
        free = self.ram_words - self.job_word - JOB_HEADER_WORDS
        return max(0, free // (POSE_WORDS + self.result_words))


def tool(name: str) -> str:
    """Path of ``riscv64-unknown-elf-<name>``; :class:`Rv32BuildError` when it is missing."""
    path = shutil.which(PREFIX + name)
    if path is None:
        raise Rv32BuildError(f"{PREFIX}{name} not found: install the RISC-V cross compiler "
                             f"(apt-get install {APT_PACKAGES}, or 'make firmware' as root)")
    return path


def _run(cmd: list[str], what: str) -> str:
    result = subprocess.run(cmd, capture_output=True, text=True)
    if result.returncode != 0:
        first = next((ln for ln in result.stderr.splitlines() if "error" in ln.lower()),
                     result.stderr.strip().splitlines()[0] if result.stderr.strip() else "")
        raise Rv32BuildError(f"{what} failed (exit {result.returncode}): {first}")
    return result.stdout


def _sections(elf: Path) -> dict[str, int]:
    out = _run([tool("size"), "-A", str(elf)], "riscv64-unknown-elf-size")
    sizes = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0].startswith(".") and parts[1].isdigit():
            sizes[parts[0]] = int(parts[1])
    return sizes


def _symbol(elf: Path, name: str) -> int:
    for line in _run([tool("nm"), str(elf)], "riscv64-unknown-elf-nm").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] == name:
            return int(parts[0], 16)
    raise Rv32BuildError(f"{elf}: symbol {name} missing")


def build(k: Constants, isa: str = "rv32im", ram_words: int = 16384,
          stack_bytes: int = STACK_BYTES, periph: bool = False) -> Firmware:
    """Build (or reuse) the firmware of config ``k`` for ``isa`` and a RAM of ``ram_words``;
    with ``periph``, the harness that solves every pose on the IK peripheral and in software."""
    if isa not in ISAS:
        raise Rv32BuildError(f"--isa must be one of {', '.join(ISAS)}, got {isa!r}")
    gcc = tool("gcc")
    version = _run([gcc, "--version"], "riscv64-unknown-elf-gcc --version").splitlines()[0]
    link = (f"-Wl,--defsym=__ram_size={4 * ram_words}", f"-Wl,--defsym=__stack_size={stack_bytes}")
    flags = ("--specs=picolibc.specs", f"-march={isa}", *CFLAGS, "-nostartfiles",
             "-Wl,--gc-sections", *link)
    headers = {HEADER_NAME: generate_header(k).encode()}
    if periph:
        headers[REGS_HEADER] = regs_header().encode()
    sources = PERIPH_SOURCES if periph else SOURCES
    digest = hashlib.sha256(b"".join(headers.values()) + version.encode() + "\0".join(flags).encode())
    for name in sources:
        digest.update(name.encode() + (SOURCE_DIR / name).read_bytes())
    kind = "fwp" if periph else "fw"
    directory = cache_root() / f"{k.cfg.name}-{k.arm.name}-{isa}-{kind}-{digest.hexdigest()[:20]}"
    elf = directory / "ik5r_rv32.elf"
    if not elf.exists():
        _compile(directory, headers, sources, [gcc, *flags, "-T", str(directory / "rv32.ld")], elf,
                 f"firmware build ({isa}, {k.cfg.name})")
    return _load(elf, isa, ram_words, stack_bytes, PERIPH_RESULT_WORDS if periph else RESULT_WORDS)


def _compile(directory: Path, headers: dict, sources: tuple, cmd: list, elf: Path, what: str) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    for name, text in headers.items():
        (directory / name).write_bytes(text)
    for name in sources:
        shutil.copyfile(SOURCE_DIR / name, directory / name)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".elf.")
    os.close(fd)
    # The link order of the original harness: start-up, the harness's main, then the rest.
    order = sorted((s for s in sources if s.endswith((".c", ".S"))),
                   key=lambda s: (not s.endswith(".S"), not s.endswith("main.c")))
    compiled = [str(directory / s) for s in order]
    try:
        _run([*cmd, "-I", str(directory), *compiled, "-o", tmp, "-lgcc"], what)
    except Rv32BuildError:
        Path(tmp).unlink(missing_ok=True)     # gcc removes its output when the link fails
        raise
    os.replace(tmp, elf)


def _load(elf: Path, isa: str, ram_words: int, stack_bytes: int, result_words: int) -> Firmware:
    binary = elf.with_suffix(".bin")
    if not binary.exists() or binary.stat().st_mtime < elf.stat().st_mtime:
        _run([tool("objcopy"), "-O", "binary", str(elf), str(binary)], "riscv64-unknown-elf-objcopy")
    data = binary.read_bytes()
    data += b"\0" * (-len(data) % 4)
    image = tuple(int.from_bytes(data[i:i + 4], "little") for i in range(0, len(data), 4))
    sizes = _sections(elf)
    data_bytes = sum(sizes.get(s, 0) for s in (".rodata", ".data", ".sdata", ".bss"))
    return Firmware(isa=isa, elf=elf, image=image, job_word=_symbol(elf, "ik5r_job") // 4,
                    ram_words=ram_words, code_bytes=sizes.get(".text", 0), data_bytes=data_bytes,
                    stack_bytes=stack_bytes, result_words=result_words)
