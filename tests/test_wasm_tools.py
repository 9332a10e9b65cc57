"""The set-up step that compiles the WebAssembly tools once (``ik5r.tools.wasm_tools``): a tool
not installed is skipped, a tool that fails is named and counted, a slow first run is announced
while it runs (a compile), a quick one says nothing."""

import io
import sys

from ik5r.tools import wasm_tools


def test_skips_missing_names_failures_and_announces_a_compile(monkeypatch):
    python = sys.executable
    monkeypatch.setattr(wasm_tools, "TOOLS", (
        ("absent", "no_such_module_ik5r", ["no-such-tool"]),
        ("quick", "json", [python, "-c", "pass"]),
        ("broken", "json", [python, "-c", "import sys; print('bad flag'); sys.exit(3)"]),
        ("slow", "json", [python, "-c", "import time; time.sleep(3.5)"]),
    ))
    out = io.StringIO()
    assert wasm_tools.warm(out) == 1
    lines = out.getvalue().splitlines()
    assert lines[0] == "ik5r: broken did not run: bad flag"
    assert lines[1] == "ik5r: compiling slow (WebAssembly, once per machine) ..."
    assert lines[2].startswith("ik5r: compiled slow in ") and len(lines) == 3
