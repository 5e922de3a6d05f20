"""The library stays readable: no module of systems/ or diagrams/ longer than MAX_LINES."""

from conftest import REPO

MAX_LINES = 400


def test_no_library_module_is_longer_than_400_lines():
    lengths = {
        str(path.relative_to(REPO)): len(path.read_text().splitlines())
        for folder in ("systems", "diagrams")
        for path in (REPO / folder).rglob("*.py")
    }
    assert len(lengths) > 100
    too_long = {name: n for name, n in lengths.items() if n > MAX_LINES}
    assert too_long == {}
