"""`guidedarm show ARM`: the arm in its scene in Meshcat, with joint sliders."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from pydrake.geometry import MeshcatVisualizer
from pydrake.multibody.meshcat import JointSliders
from pydrake.multibody.parsing import ModelDirectives, ProcessModelDirectives
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.run_context import MakeMeshcat, PrepareOutputDirectory
from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.diagrams.station.scene_views import ARM_SCENES, SceneDirectives
from guidedarm.systems.errors import ConfigurationError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("show", help="show an arm in Meshcat with joint sliders")
    parser.add_argument("arm", help=f"one of {', '.join(ARM_SCENES)} or a directive name")
    parser.add_argument("--html", type=Path, help="write an offline page instead of serving")
    parser.add_argument("--timeout", type=float, help="stop serving after this many seconds")
    parser.add_argument(
        "--meshcat-host",
        metavar="HOST",
        help="the address Meshcat listens on (default localhost)",
    )
    parser.set_defaults(func=show_command)


def show_command(args: argparse.Namespace) -> int:
    if args.timeout is not None and not 0 <= args.timeout < math.inf:
        raise ConfigurationError(f"--timeout must be >= 0 s, got {args.timeout}")
    if args.html is not None and (args.timeout is not None or args.meshcat_host is not None):
        raise ConfigurationError(
            "--html writes a page and serves nothing: drop --timeout and --meshcat-host"
        )
    if args.html is not None:
        PrepareOutputDirectory(args.html.parent, "--html")
        if args.html.is_dir():
            raise ConfigurationError(f"--html {args.html} is a directory")
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    ProcessModelDirectives(ModelDirectives(directives=SceneDirectives(args.arm)), MakeParser(plant))
    plant.Finalize()
    meshcat = MakeMeshcat(serve=args.html is None, host=args.meshcat_host or "localhost")
    MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    if args.html:
        diagram = builder.Build()
        diagram.ForcedPublish(diagram.CreateDefaultContext())
        args.html.write_text(meshcat.StaticHtml())
        print(f"wrote {args.html}")
        return 0
    sliders = builder.AddSystem(JointSliders(meshcat, plant))
    diagram = builder.Build()
    print(f"Meshcat: {meshcat.web_url()} (press Escape or the Stop button to quit)", flush=True)
    sliders.Run(diagram, args.timeout)
    return 0
