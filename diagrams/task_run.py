"""Running one task on its resolved scenario: what `guidedarm run` and each campaign job do."""

from __future__ import annotations

import time
from typing import Any

from pydrake.common.yaml import yaml_dump_typed

from guidedarm.diagrams.run_context import RESOLVED_SCENARIO_FILE, RunContext
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.systems.errors import RunFailedError

# The `failure` of a run stopped by Ctrl-C.
INTERRUPTED = "interrupted"


def RunTask(task: TaskDefinition, scenario: Any, context: RunContext) -> dict[str, Any]:
    """Writes DIR/scenario.yaml (the fully resolved scenario), runs the task and returns its
    metrics plus `wall_time_s` (s). A RunFailedError or Ctrl-C during the run ends it with
    `success` false and `failure` naming the cause; bad input (ConfigurationError) is
    raised."""
    context.write_text(RESOLVED_SCENARIO_FILE, yaml_dump_typed(scenario))
    wall_start = time.perf_counter()
    try:
        metrics = task.run(scenario, context)
    except RunFailedError as e:
        metrics = {"success": False, "failure": str(e)}
    except KeyboardInterrupt:
        metrics = {"success": False, "failure": INTERRUPTED}
    metrics["wall_time_s"] = round(time.perf_counter() - wall_start, 3)
    return metrics
