"""The documentation site builds in strict mode (a broken internal link, a missing anchor, a
page left out of the navigation or any other warning fails it), with the command-line
reference made from the parsers and an API reference page per module. The tutorials are
executed by tests/test_tutorials.py; here they are rendered without running."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from conftest import REPO

from guidedarm.diagrams.cli.main import MakeArgumentParser
from guidedarm.diagrams.cli.reference import CommandLineReference


@pytest.mark.slow
def test_the_site_builds_in_strict_mode_without_a_warning(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "GUIDEDARM_DOCS_EXECUTE": "false"}
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=REPO,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    log = result.stdout + result.stderr
    assert result.returncode == 0, log
    assert not re.search(r"^(WARNING|ERROR)", log, re.MULTILINE), log
    site = tmp_path / "site"
    home = (site / "index.html").read_text()
    assert 'href="results/"' in home and "guidedarm.png" in home
    assert (
        site / "reference" / "systems" / "planning" / "acceleration_planner" / "index.html"
    ).is_file()
    assert (
        "Stops the recording StartReplay began"
        in (site / "reference" / "diagrams" / "run_context" / "index.html").read_text()
    )
    for page in (REPO / "docs").glob("*.md"):  # every page is built, none left out
        assert (site / page.stem / "index.html").is_file(), page.name


def test_the_command_line_reference_has_every_command_and_option():
    text = CommandLineReference()
    parser = MakeArgumentParser()
    (subparsers,) = [a for a in parser._actions if a.choices and isinstance(a.choices, dict)]
    for name, subparser in subparsers.choices.items():
        assert f"## guidedarm {name}\n" in text
        for action in subparser._actions:
            for option in action.option_strings:
                assert option in text, f"{name} {option}"
    assert "--metrics" in text and "--panel" in text
