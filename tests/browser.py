"""Headless Chromium for the page tests: Debian's chromium, offline, software WebGL."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np

CHROMIUM = shutil.which("chromium")
MISSING = "Debian chromium missing: `make test` installs it"


def Screenshot(page: Path, out: Path, size=(800, 600), budget_ms=8000) -> np.ndarray:
    """An RGB screenshot (float) of `page` at `size`, its profile and PNG under `out`."""
    png = out.with_suffix(".png")
    subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            f"--user-data-dir={out}",
            f"--window-size={size[0]},{size[1]}",
            f"--virtual-time-budget={budget_ms}",
            f"--screenshot={png}",
            page.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return cv2.imread(str(png))[:, :, ::-1].astype(float)
