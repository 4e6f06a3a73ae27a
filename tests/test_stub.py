"""The compiled module's type stub is written from the module (python/softrast/_stubgen.py): the
committed python/softrast/_core.pyi must be exactly what the installed build generates."""
import pathlib

from softrast import _core, _stubgen

STUB = pathlib.Path(__file__).resolve().parents[1] / "python" / "softrast" / "_core.pyi"


def _ours(text: str) -> list[str]:
    """The stub's lines but the ones whose spelling is pybind11's (signatures, its version)."""
    return [line for line in text.splitlines()
            if not line.lstrip().startswith(("def ", "@typing.overload", "Written by", "spells them"))]


def test_committed_stub_is_what_the_bindings_generate():
    committed, generated = STUB.read_text(), _stubgen.generate()
    if f"pybind11 {_stubgen.pybind11_version()}" in committed:
        assert committed == generated, \
            "python/softrast/_core.pyi is stale: run python -m softrast._stubgen from the repository"
    else:  # another pybind11 spells signatures differently: compare everything else
        assert _ours(committed) == _ours(generated)
        assert sum(line.lstrip().startswith("def ") for line in committed.splitlines()) == \
            sum(line.lstrip().startswith("def ") for line in generated.splitlines())


def test_stub_names_every_record_field_and_option():
    text = STUB.read_text()
    for record, fields in _core.RECORDS.items():
        assert f"class {record}:" in text
        for name, typ, _ in fields:
            assert f"    {name}: {typ}  #" in text
    for name, *_ in _core.RENDER_OPTIONS:
        assert f"    {name}: " in text


def test_check_mode_fails_on_a_stale_stub(tmp_path):
    stale = tmp_path / "_core.pyi"
    stale.write_text(_stubgen.generate().replace("class Light:", "class Lamp:"))
    assert _stubgen.main(["--check", str(stale)]) == 1
    stale.write_text(_stubgen.generate())
    assert _stubgen.main(["--check", str(stale)]) == 0
