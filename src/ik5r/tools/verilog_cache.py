"""One cached way to the Verilog and port map of a design point (``ik5r.hdl.generate.generate``).

:func:`generate_cached` keeps the body and the port map under ``build/verilog-cache/``, keyed by
everything they depend on; :meth:`ik5r.tools.design.Design.verilog` is its front door. It
imports only the generator's side (no testbench, no firmware model), so the synthesis cache
keys that hash the generator's import closure stay what they were.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import threading
from pathlib import Path

from ik5r.core.cbuild import path_lock

ROOT = Path(__file__).resolve().parents[3]


#: Generated Verilog bodies and port maps, by :func:`generate_cached`'s key.
VERILOG_CACHE = ROOT / "build" / "verilog-cache"


@functools.cache
def _generator_sources_hash() -> str:
    """Hash of every source file the Verilog comes from (the import closure of the generator, and
    the compact core's kept block orders: data its programs are scheduled by)."""
    from ik5r.hdl.sequenced.hints import schedule_files
    from ik5r.tools.sources import closure_hash
    return closure_hash(["ik5r.hdl.generate"], schedule_files())


def generate_cached(block: str, arch: str, k, tag_width: int = 0, **options) -> tuple[str, dict]:
    """``ik5r.hdl.generate.generate(block, arch, k, tag_width, **options)``, the body and port map
    kept in :data:`VERILOG_CACHE` under a key of everything they depend on: the arguments, the
    config's name and numbers and the arm, the files of the generator's import closure, the tool
    and Python versions. A hit gets a fresh header (this checkout's commit). Converting an IK core
    takes tens of seconds; the testbenches and the lint test share one conversion. ``make clean``
    empties the cache (entries of older sources are not pruned)."""
    from ik5r.hdl.generate import generate
    from ik5r.hdl.provenance import config_hash, strip_header, tool_versions, verilog_header

    key = hashlib.sha256(json.dumps(
        [block, arch, tag_width, sorted(options.items()), k.cfg.name, k.arm.name, config_hash(k),
         _generator_sources_hash(), tool_versions(), platform.python_version()],
        default=str).encode()).hexdigest()[:24]
    body_path, map_path = VERILOG_CACHE / f"{key}.v", VERILOG_CACHE / f"{key}.json"
    VERILOG_CACHE.mkdir(parents=True, exist_ok=True)
    # One conversion per key: a test process asking for a design another is converting waits
    # for it and reads the cache (xdist workers often need the same IK core at the same time).
    with path_lock(VERILOG_CACHE / f"{key}.lock"):
        if body_path.is_file() and map_path.is_file():
            pmap = json.loads(map_path.read_text())
            return verilog_header(pmap, k, options) + body_path.read_text(), pmap
        text, pmap = generate(block, arch, k, tag_width, **options)
        for path, content in ((body_path, strip_header(text)), (map_path, json.dumps(pmap))):
            tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text(content)
            os.replace(tmp, path)      # atomic: a reader without the lock sees the old or the new file
    return text, json.loads(json.dumps(pmap))
