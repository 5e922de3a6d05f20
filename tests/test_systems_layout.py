"""systems/ stays readable: no module of it longer than MAX_LINES."""

from conftest import REPO

MAX_LINES = 400
# Modules that still wait for their split, by path under systems/.
LONGER = {"config_checks.py"}


def test_no_systems_module_is_longer_than_400_lines():
    lengths = {
        str(path.relative_to(REPO / "systems")): len(path.read_text().splitlines())
        for path in (REPO / "systems").rglob("*.py")
    }
    assert len(lengths) > 50
    too_long = {name: n for name, n in lengths.items() if n > MAX_LINES and name not in LONGER}
    assert too_long == {}
