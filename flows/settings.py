"""Prefect defaults for running on one machine with no set-up: the embedded ephemeral server, no
analytics, quiet logs, and a PREFECT_HOME under the project's output folder unless the user set one.
A user with a Prefect server exports ``PREFECT_API_URL`` and these defaults leave it alone."""

from __future__ import annotations

import os
import urllib.error
import urllib.request
from pathlib import Path

DEFAULTS = {
    "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
    "PREFECT_LOGGING_LEVEL": "WARNING",
    # run logs (stage lines) reach the API at INFO; the console shows PREFECT_LOGGING_LEVEL and above
    "PREFECT_LOGGING_LOGGERS_PREFECT_FLOW_RUNS_LEVEL": "INFO",
    "PREFECT_LOGGING_LOGGERS_PREFECT_TASK_RUNS_LEVEL": "INFO",
    "PREFECT_SERVER_UI_ENABLED": "false",
    "PREFECT_TELEMETRY_ENABLE_RESOURCE_METRICS": "false",
    "PREFECT_CLOUD_ENABLE_ORCHESTRATION_TELEMETRY": "false",
    "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS": "90",
}


def configure(home: str | os.PathLike | None = None) -> None:
    """Set the defaults above where the user has not set them (call before importing prefect). Run logs are
    sent to the user's own server (``PREFECT_API_URL`` set: its UI shows them), not to the embedded one."""
    for key, value in DEFAULTS.items():
        os.environ.setdefault(key, value)
    os.environ.setdefault("PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL", os.environ["PREFECT_LOGGING_LEVEL"])
    if not os.environ.get("PREFECT_API_URL"):
        os.environ.setdefault("PREFECT_LOGGING_TO_API_ENABLED", "false")
    if "PREFECT_HOME" not in os.environ:
        os.environ["PREFECT_HOME"] = str(Path(home or "outputs/.prefect").resolve())
    Path(os.environ["PREFECT_HOME"]).mkdir(parents=True, exist_ok=True)


def check_api_reachable(timeout_s: float = 5.0) -> None:
    """If ``PREFECT_API_URL`` is set, fail within ``timeout_s`` with a one-line error when it is down."""
    url = os.environ.get("PREFECT_API_URL")
    if not url:
        return
    try:
        urllib.request.urlopen(url.rstrip("/") + "/health", timeout=timeout_s)
    except (urllib.error.URLError, OSError, ValueError) as exc:
        raise ConnectionError(
            f"Prefect API at PREFECT_API_URL={url} is unreachable ({exc}); start the server or unset "
            f"PREFECT_API_URL to use the embedded one") from None
