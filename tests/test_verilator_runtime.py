"""The cache of Verilator's runtime objects (``ik5r.core.verilator_runtime``): one per
installation and flag set. Two venvs with the same Verilator version must not share objects:
their dependency files name the headers of one installation by absolute path."""

from ik5r.core import verilator_runtime


def _fake_verilator(folder, version="Verilator 5.0 fake"):
    folder.mkdir()
    tool = folder / "verilator"
    tool.write_text(f"#!/bin/sh\necho '{version}'\n")
    tool.chmod(0o755)
    return str(tool)


def test_cache_is_per_installation_and_flags(tmp_path):
    one, other = _fake_verilator(tmp_path / "venv1"), _fake_verilator(tmp_path / "venv2")
    folder = verilator_runtime._folder
    assert folder(one, ["-O0"]) == folder(one, ["-O0"])
    assert folder(one, ["-O0"]) != folder(other, ["-O0"])
    assert folder(one, ["-O0"]) != folder(one, ["-O1"])


def test_seeded_objects_come_back_and_are_kept_once(tmp_path, monkeypatch):
    monkeypatch.setenv("IK5R_CACHE_DIR", str(tmp_path / "cache"))
    tool = _fake_verilator(tmp_path / "venv")
    first, second = tmp_path / "obj1", tmp_path / "obj2"
    with verilator_runtime.reusing_runtime(tool, first, ["-O0"]):
        first.mkdir()
        (first / "verilated.o").write_bytes(b"object")
        (first / "model.o").write_bytes(b"not the runtime's")
    with verilator_runtime.reusing_runtime(tool, second, ["-O0"]):
        assert (second / "verilated.o").read_bytes() == b"object"
        assert not (second / "model.o").exists()


def test_objects_of_another_key_left_in_the_folder_are_dropped(tmp_path, monkeypatch):
    """A build folder seeded under another key (another venv) before: with nothing kept for this
    key yet, its runtime objects go (make would link them, or stop at their headers), the
    model's stay."""
    monkeypatch.setenv("IK5R_CACHE_DIR", str(tmp_path / "cache"))
    tool = _fake_verilator(tmp_path / "venv")
    obj = tmp_path / "obj"
    obj.mkdir()
    for name in ("verilated.o", "verilated.d", "model.o"):
        (obj / name).write_bytes(b"old")
    with verilator_runtime.reusing_runtime(tool, obj, ["-O0"]):
        assert sorted(p.name for p in obj.iterdir()) == ["model.o"]
