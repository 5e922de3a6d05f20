"""Headless Chromium for the page tests: Debian's chromium, offline, software WebGL."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from pathlib import Path

import cv2
import numpy as np

CHROMIUM = shutil.which("chromium")
MISSING = "Debian chromium missing: `make test` installs it"


def Screenshot(page: Path, out: Path, size=(800, 600), budget_ms=8000) -> np.ndarray:
    """An RGB screenshot (float) of `page` at `size`, its profile and PNG under `out`.
    Headless Chromium on loaded cores sometimes never ends its virtual-time budget (seen
    once in 1279 tests of a full run; 11-14 s otherwise): such a launch is killed, with its
    child processes, after 60 s and tried once more with a new profile."""
    png = out.with_suffix(".png")
    for attempt in range(2):
        profile = out.with_name(f"{out.name}-{attempt}")
        command = [CHROMIUM, *FLAGS, f"--user-data-dir={profile}"]
        command += [f"--window-size={size[0]},{size[1]}", f"--virtual-time-budget={budget_ms}"]
        command += [f"--screenshot={png}", page.as_uri()]
        if _RunKillingTheGroup(command, timeout=60.0):
            return cv2.imread(str(png))[:, :, ::-1].astype(float)
    raise TimeoutError(f"chromium did not screenshot {page} in two launches of 60 s")


FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)


def _RunKillingTheGroup(command: list[str], timeout: float) -> bool:
    """Runs `command` in its own process group; True when it exited 0 within `timeout` s.
    On timeout the whole group (Chromium's renderer and GPU processes) is killed."""
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
    )
    try:
        _, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        return False
    if process.returncode != 0:
        raise RuntimeError(f"chromium exited {process.returncode}: {stderr.decode()[-500:]}")
    return True
