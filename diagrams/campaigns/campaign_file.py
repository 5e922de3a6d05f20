"""Reading a campaign file (its format: campaign.py's docstring). LoadCampaign finds a named
campaign (diagrams/campaigns/NAME.yaml) or a file, refuses unknown keys and malformed axes
in one line naming the file and the key, and returns the checked CampaignConfig."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from guidedarm.diagrams.campaigns.campaign import (
    CAMPAIGN_DIR,
    CAMPAIGN_KEYS,
    MAX_JOBS,
    CampaignConfig,
    CampaignError,
    RandomDrawsConfig,
    RepeatConfig,
)
from guidedarm.diagrams.scenario_loading import ListNamedFiles, ResolveNamedFile, read_raw_scenario


def ResolveCampaignPath(name_or_path: str) -> Path:
    """The file of a named campaign (diagrams/campaigns/NAME.yaml) or a path."""
    return ResolveNamedFile(name_or_path, CAMPAIGN_DIR, "campaign", CampaignError)


def ListNamedCampaigns() -> list[str]:
    """Names of the campaigns shipped in diagrams/campaigns/."""
    return ListNamedFiles(CAMPAIGN_DIR)


def LoadCampaign(name_or_path: str) -> CampaignConfig:
    """Reads and checks a campaign file; refuses unknown keys and empty or malformed axes
    with one line naming the file and the key."""
    path = ResolveCampaignPath(name_or_path)
    raw = read_raw_scenario(path)
    source = str(path)
    unknown = sorted(set(raw) - set(CAMPAIGN_KEYS))
    if unknown:
        raise CampaignError(
            f"{source}: unknown key '{unknown[0]}' (known keys: {', '.join(CAMPAIGN_KEYS)})"
        )
    scenario = raw.get("scenario")
    if not isinstance(scenario, str) or not scenario:
        raise CampaignError(f"{source}: missing key 'scenario' (a scenario name or file)")
    beside = path.parent / scenario
    if Path(scenario).suffix in (".yaml", ".yml") and beside.is_file():
        scenario = str(beside.resolve())
    campaign = CampaignConfig(
        name=_Text(raw, "name", source) or path.stem,
        scenario=scenario,
        source=source,
        description=_Text(raw, "description", source),
        set=_Mapping(raw, "set", source),
        grid={k: _Values(v, f"grid.{k}", source) for k, v in _Mapping(raw, "grid", source).items()},
        zip={k: _Values(v, f"zip.{k}", source) for k, v in _Mapping(raw, "zip", source).items()},
        random=_Struct(RandomDrawsConfig, raw, "random", source),
        repeat=_Struct(RepeatConfig, raw, "repeat", source),
        metrics=raw.get("metrics"),
    )
    campaign.Validate()
    return campaign


def _Text(raw: dict[str, Any], key: str, source: str) -> str:
    value = raw.get(key, "")
    if not isinstance(value, str):
        raise CampaignError(f"{source}: key '{key}' must be a string, got {value!r}")
    return value


def _Mapping(raw: dict[str, Any], key: str, source: str) -> dict[str, Any]:
    value = raw.get(key) or {}
    if not isinstance(value, dict):
        raise CampaignError(f"{source}: key '{key}' must be a mapping of scenario keys")
    return value


def _Values(value: Any, key: str, source: str) -> list[Any]:
    """A grid or zip axis: a list, {linspace: [first, last, count]} or {range: [start, stop,
    step]}; finite numbers, at most MAX_JOBS values."""
    if isinstance(value, list):
        return value
    if isinstance(value, dict) and len(value) == 1:
        (kind, args) = next(iter(value.items()))
        if kind in ("linspace", "range") and isinstance(args, list) and len(args) == 3:
            for a in args:
                if isinstance(a, bool) or not isinstance(a, int | float) or not math.isfinite(a):
                    raise CampaignError(
                        f"{source}: {key}.{kind}: {a!r} is not a finite number{_TextHint(a)}"
                    )
            if kind == "linspace":
                count = _Count(args[2], f"{key}.linspace count", source)
                return [round(float(v), 12) for v in np.linspace(args[0], args[1], count)]
            start, stop, step = args
            if step == 0:
                raise CampaignError(f"{source}: {key}.range: step must not be 0")
            _Count(max(math.ceil((stop - start) / step), 0), f"{key}.range length", source)
            values = np.arange(start, stop, step)
            return [round(v, 12) if isinstance(v, float) else v for v in values.tolist()]
    raise CampaignError(
        f"{source}: {key} must be a list, {{linspace: [first, last, count]}} or "
        f"{{range: [start, stop, step]}}, got {value!r}"
    )


def _TextHint(value: Any) -> str:
    """Why a number written as `1e12` is text: YAML 1.1 floats need a dot and a signed
    exponent."""
    try:
        return f" (YAML reads it as text: write {float(value):.1e})"
    except (TypeError, ValueError):
        return ""


def _Count(value: float, what: str, source: str) -> int:
    """A number of values: a whole number from 1 to MAX_JOBS."""
    if value != int(value) or not 1 <= value <= MAX_JOBS:
        raise CampaignError(
            f"{source}: {what} must be a whole number from 1 to {MAX_JOBS}, got {value:g}"
        )
    return int(value)


def _Struct(schema: type, raw: dict[str, Any], key: str, source: str) -> Any:
    value = raw.get(key)
    if value is None:
        return None
    if not isinstance(value, dict):
        raise CampaignError(f"{source}: key '{key}' must be a mapping")
    known = list(schema.__dataclass_fields__)
    for name in value:
        if name not in known:
            raise CampaignError(
                f"{source}: unknown key '{key}.{name}' (known keys: {', '.join(known)})"
            )
    config = schema(**value)
    for name, expected in (("seed", int), ("count", int), ("start", int), ("key", str)):
        item = getattr(config, name, None)
        if item is not None and (isinstance(item, bool) or not isinstance(item, expected)):
            raise CampaignError(f"{source}: key '{key}.{name}' must be {expected.__name__}")
    return config
