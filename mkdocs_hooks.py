"""MkDocs hooks of the documentation site (mkdocs.yml).

- The navigation: the user guide lists every docs/*.md page (GUIDE_ORDER first, any other
  page after them, by name), so a new page needs no edit here; then the tutorials, then
  the reference.
- Generated pages: index.md from README.md (its links into docs/ made relative), cli.md
  from the command-line parsers (CommandLineReference), and one API reference page per
  module of guidedarm.systems and guidedarm.diagrams, rendered from its docstrings by
  mkdocstrings.
- Links from a page to files outside docs/ (examples, sources) become the file's path in
  code: the site holds only docs/.
"""

from __future__ import annotations

import pkgutil
import re
from pathlib import Path

from mkdocs.structure.files import File, Files

REPO = Path(__file__).resolve().parent
# The user guide's first pages, in reading order; other docs/*.md pages follow by name.
GUIDE_ORDER = [
    "usage.md",
    "planner.md",
    "path_following.md",
    "panel_operation.md",
    "campaigns.md",
    "hardware.md",
    "nachi_protocol.md",
    "views.md",
    "results.md",
    "layout.md",
]
# Pages of the reference section, not of the guide.
REFERENCE_PAGES = ["api.md", "cli.md"]
# The packages whose modules get an API reference page, and the folders they live in; the
# command-line modules are documented by the command-line reference instead.
REFERENCE_PACKAGES = {"guidedarm.systems": "systems", "guidedarm.diagrams": "diagrams"}
NOT_REFERENCED = ("guidedarm.diagrams.cli.",)
_LINK = re.compile(r"\[([^\]]*)\]\(([^)\s#]+)(#[^)\s]*)?\)")


def ReferenceModules() -> list[str]:
    """Every module of REFERENCE_PACKAGES (dotted names), found on disk, sorted."""
    modules = []
    for package, folder in REFERENCE_PACKAGES.items():
        for info in pkgutil.walk_packages([str(REPO / folder)], f"{package}."):
            if not info.ispkg and not info.name.startswith(NOT_REFERENCED):
                modules.append(info.name)
    return sorted(modules)


def _ReferencePath(module: str) -> str:
    return "reference/" + module.removeprefix("guidedarm.").replace(".", "/") + ".md"


def on_config(config):

    docs = Path(config["docs_dir"])
    pages = sorted(p.name for p in docs.glob("*.md") if p.name not in ("index.md",))
    guide = [p for p in GUIDE_ORDER if p in pages]
    guide += [p for p in pages if p not in GUIDE_ORDER and p not in REFERENCE_PAGES]
    tutorials = sorted(str(p.relative_to(docs)) for p in (docs / "tutorials").glob("*.ipynb"))
    groups: dict[str, list[str]] = {}
    for module in ReferenceModules():
        package = module.rsplit(".", 1)[0]
        groups.setdefault(package, []).append(_ReferencePath(module))
    config["nav"] = [
        {"Home": "index.md"},
        {"User guide": guide},
        {"Tutorials": tutorials},
        {
            "Reference": [
                {"Python API": "api.md"},
                {"Command line": "cli.md"},
                {"Docstrings": [{package: paths} for package, paths in groups.items()]},
            ]
        },
    ]
    return config


def on_files(files: Files, config) -> Files:
    from guidedarm.diagrams.cli.reference import CommandLineReference

    files.append(File.generated(config, "index.md", content=_HomePage()))
    files.append(File.generated(config, "cli.md", content=CommandLineReference()))
    for module in ReferenceModules():
        content = f"# {module}\n\n::: {module}\n"
        files.append(File.generated(config, _ReferencePath(module), content=content))
    return files


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Links to files outside docs/ become their repository path in code."""
    if page.file.generated_by or page.file.src_uri.endswith(".ipynb"):
        return markdown

    def Outside(match: re.Match) -> str:
        target = match.group(2)
        if not target.startswith("../"):
            return match.group(0)
        return f"{match.group(1)} (`{target.removeprefix('../')}`)"

    return _LINK.sub(Outside, markdown)


def _HomePage() -> str:
    """README.md with its links into docs/ made relative to the site and its other links
    to repository files shown as paths."""

    def Relative(match: re.Match) -> str:
        text, target, anchor = match.group(1), match.group(2), match.group(3) or ""
        if target.startswith(("http://", "https://")):
            return match.group(0)
        if target.startswith("docs/"):
            return f"[{text}]({target.removeprefix('docs/')}{anchor})"
        return f"{text} (`{target}`)"

    return _LINK.sub(Relative, (REPO / "README.md").read_text())
