"""`guidedarm marker-study distance|tilt|repeatability|press|occlusion [--out DIR]`.

Each study reproduces one table of Annusewicz-Mistal et al. in simulation by running its campaigns
(diagrams/campaigns/marker_*.yaml) through the sweep engine, then writes DIR/<study>.csv
and DIR/<study>.png from the campaigns' results (each campaign's own results.csv,
campaign.yaml and report.html are in DIR/<campaign>/):
  distance       Table 2: camera distance from the left marker, 200-430 mm, straight on and
                 with the view angle growing to 24 deg (the paper's second series);
  tilt           Table 3: rotation about the panel's y axis, 0-26 deg at 300 mm;
  repeatability  Table 4: the base position (170 mm) reached from 16 random starts;
  press          Table 5: the tip position while pressing, 10 runs from random starts;
  occlusion      Table 6: markers covered after the base position, both policies.
The first two run task marker_view (a free camera: exact ground truth, as the paper's
IRB 1600); the others the whole panel_operation task. --noise, --blur and --lighting
degrade the images (ImageDegradation; each job's noise seed is its random_seed). A rerun
into the same DIR runs only the jobs not done yet. Exit 0 when every job gave its row as
expected, 1 when some failed (counted on the last line), 2 for bad input, 130 when
interrupted.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from guidedarm.diagrams.campaigns.sweep import MakeSweepOptions
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.studies.marker_study import (
    DEGRADATION_FLAGS,
    STUDIES,
    CheckedCampaigns,
    RunStudy,
    StudyCamera,
)
from guidedarm.systems.config_checks import FieldError
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig

EXIT_FAILED = 1
EXIT_INTERRUPTED = 130


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "marker-study", help="reproduce Annusewicz-Mistal et al.'s accuracy tables in simulation"
    )
    parser.add_argument("study", choices=STUDIES)
    parser.add_argument("--out", type=Path, help="output directory (default runs/marker_study)")
    parser.add_argument("--noise", type=float, default=0.0, help="noise std (grey levels)")
    parser.add_argument("--blur", type=float, default=0.0, help="blur sigma (px)")
    parser.add_argument("--lighting", type=float, default=1.0, help="brightness scale")
    parser.add_argument(
        "--panel",
        help="your own PANEL.yaml (a path, or a name under models/; default the paper's panel): "
        "every job's scene and estimator use it",
    )
    parser.add_argument(
        "--camera-file",
        help="the estimator's camera model, a CAMERA.yaml (e.g. from `guidedarm calibrate "
        "camera`; a path, or a name under models/): every job's estimator_camera_file",
    )
    parser.add_argument(
        "--lens",
        type=_Lens,
        metavar="K1,K2,P1,P2,K3",
        help="the real camera's lens (OpenCV distortion), which the estimator does not know "
        "unless --camera-file models it: every job renders through it (camera_errors)",
    )
    parser.add_argument("--workers", type=int, help="local worker processes (default: cores)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler")
    parser.set_defaults(func=study_command)


def study_command(args: argparse.Namespace) -> int:
    options = MakeSweepOptions(args.workers, args.scheduler)
    # No seed: each job's noise follows its scenario's random_seed (SeededDegradation).
    degradation = DegradationConfig(
        lighting=args.lighting, blur_sigma_px=args.blur, noise_std=args.noise
    )
    try:
        degradation.Validate()
    except FieldError as e:
        raise ConfigurationError(f"{DEGRADATION_FLAGS.get(e.key, e.key)}: {e.why}") from None
    camera = StudyCamera(args.camera_file, args.lens)
    checked = CheckedCampaigns(args.study, degradation, args.panel, camera)
    context = RunContext(out_dir=args.out or Path("runs") / "marker_study")
    result = RunStudy(args.study, checked, context, options)
    if result is None:
        return EXIT_INTERRUPTED
    for key, value in result.summary.items():
        print(f"  {key}: {value}")
    print("wrote:")
    for path in context.written:
        print(f"  {path}")
    jobs = sum(len(rows) for rows in result.rows)
    print(f"  failed: {len(result.failed)} of {jobs} job(s)")
    return EXIT_FAILED if result.failed else 0


def _Lens(text: str) -> tuple[float, ...]:
    """--lens K1,K2,P1,P2,K3 as five numbers."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 5 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"five finite numbers K1,K2,P1,P2,K3, got '{text}'")
    return values
