"""A dataset's recording set, what its demos record (cameras, observation terms, task options, from its
``env_args``), and the one-line refusal of an append that would mix demos of another set into it."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any


def recording_set(env_args: Mapping[str, Any]) -> dict[str, Any] | None:
    """What a dataset's demos record, from its ``env_args``: the cameras (resolution and data of each), the
    observation terms (``obs_mode`` changes them) and the task options; None for env_args that do not say (a
    writer that only appends, e.g. the writer process)."""
    nl = env_args.get("newton_lab")
    if not isinstance(nl, Mapping):
        return None
    cams = nl.get("cameras") or {}
    return {
        "cameras": {n: (c.get("width"), c.get("height"), tuple(c.get("data", ()))) for n, c in cams.items()},
        "obs_terms": {k: list(v) for k, v in (nl.get("obs_terms") or {}).items()},
        "task_options": dict((env_args.get("env_kwargs") or {}).get("task_options") or {}),
    }


def _cameras_text(cameras: Mapping[str, tuple]) -> str:
    return ",".join(f"{n}={w}x{h}:{'+'.join(d)}" for n, (w, h, d) in cameras.items()) or "none"


def check_same_recording(
    path: Path, recorded: Mapping[str, Any], new: Mapping[str, Any], option_defaults: Mapping[str, Any] | None = None
) -> None:
    """Appending to ``path`` (recorded with env_args ``recorded``) demos made with env_args ``new``: refused in one
    line when they record other cameras, other observation terms or other task options (a dataset's recording set
    is part of what it is; demos that mix them train and export wrongly). ``option_defaults``: the task's option
    defaults, for an option one side left unset (else only options both sides name are compared)."""
    before, now = recording_set(recorded), recording_set(new)
    if before is None or now is None:
        return
    defaults = {k: v for k, v in (option_defaults or {}).items() if v is not None}
    for side in (before, now):
        side["task_options"] = {**defaults, **side["task_options"]}
    if before["cameras"] != now["cameras"]:
        raise ValueError(
            f"{path} was recorded with cameras {_cameras_text(before['cameras'])}, not "
            f"{_cameras_text(now['cameras'])}; append with --cameras {_cameras_text(before['cameras'])}, "
            "or collect into another path"
        )
    for name in before["task_options"].keys() & now["task_options"].keys():
        if before["task_options"][name] != now["task_options"][name]:
            flag = "--" + name.replace("_", "-")
            raise ValueError(
                f"{path} was recorded with {flag} {before['task_options'][name]}, not "
                f"{now['task_options'][name]}; append with {flag} {before['task_options'][name]}, or "
                "collect into another path"
            )
    if before["obs_terms"] and now["obs_terms"] and before["obs_terms"] != now["obs_terms"]:
        theirs, ours = set(before["obs_terms"]), set(now["obs_terms"])
        diff = sorted(theirs ^ ours) or sorted(k for k in theirs if before["obs_terms"][k] != now["obs_terms"][k])
        raise ValueError(
            f"{path} records other observation terms ({', '.join(diff)} differ: another --obs-mode or "
            "task options); append with the settings it was recorded with, or collect into another path"
        )
