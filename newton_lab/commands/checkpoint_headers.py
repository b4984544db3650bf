"""Light readers for the command line's checks: what a checkpoint says about itself, read without torch.

A checkpoint is ``torch.save``'s zip: ``<name>/data.pkl`` (the pickled payload) beside one member per tensor
storage. ``checkpoint_header`` unpickles ``data.pkl`` alone, with every torch object (tensors, storages) read as
``None``: the format tag, version, config and ``info`` (task id, observation keys, image shapes) come back in
milliseconds, and no tensor is materialised. The full load (``DiffusionPolicy.load``) checks the rest.
"""

from __future__ import annotations

import collections
import pickle
import zipfile
from pathlib import Path
from typing import Any

CHECKPOINT_FORMAT = "newton_lab.policies.diffusion"
"""``newton_lab.policies.diffusion.CHECKPOINT_FORMAT`` (tests/test_cli_inputs.py checks they agree)."""
CHECKPOINT_VERSION = 1
"""``newton_lab.policies.diffusion.CHECKPOINT_VERSION``: the newest this newton_lab reads."""
RL_CHECKPOINT_FORMAT = "newton_lab.policies.rl"
"""``newton_lab.policies.rl.agent.CHECKPOINT_FORMAT``: a PPO actor (``newton-lab train-rl``), version 1 too."""
SAFE = {
    ("collections", "OrderedDict"): collections.OrderedDict,
    ("builtins", "set"): set,
    ("builtins", "frozenset"): frozenset,
    ("builtins", "slice"): slice,
}
"""Non-torch globals a checkpoint's pickle may name (what ``torch.load(weights_only=True)`` accepts too)."""


def _torch_object(*args: Any, **kwargs: Any) -> None:
    """Stands for every torch global of the pickle (a tensor rebuilt, a storage type): read as None."""
    return None


class _HeaderUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if module == "torch" or module.startswith("torch."):
            return _torch_object
        if (module, name) in SAFE:
            return SAFE[(module, name)]
        raise pickle.UnpicklingError(f"global {module}.{name} is not allowed in a checkpoint")

    def persistent_load(self, pid: Any) -> None:  # a tensor's storage: not read
        return None


def checkpoint_header(path: str | Path, label: str = "checkpoint") -> dict[str, Any]:
    """The payload of checkpoint ``path`` with its tensors as None (``format``, ``version``, ``config``, ``info``);
    a one-line ``ValueError`` / ``FileNotFoundError`` naming ``label`` (the flag) when it is no newton_lab
    diffusion-policy checkpoint: a folder, text, garbage, a truncated file, another format or a newer version."""
    p = Path(path)
    where = f"{label}{p}" if label.endswith("=") else f"{label} {p}"

    def damaged(reason: str) -> ValueError:
        return ValueError(
            f"{where} is not a newton_lab diffusion-policy checkpoint or is damaged ({reason}); "
            "give a checkpoint.pt written by newton-lab train"
        )

    if not p.exists():
        raise FileNotFoundError(f"{where} does not exist; check the path")
    if p.is_dir():
        raise ValueError(f"{where} is a folder; give the checkpoint file in it (e.g. {p / 'checkpoint.pt'})")
    try:
        with zipfile.ZipFile(p) as z:
            names = [n for n in z.namelist() if n == "data.pkl" or n.endswith("/data.pkl")]
            if not names:
                raise damaged("no data.pkl in it")
            payload = _HeaderUnpickler(z.open(names[0])).load()
    except ValueError:
        raise
    except (zipfile.BadZipFile, EOFError):
        raise damaged("not a torch.save zip, or truncated") from None
    except (pickle.UnpicklingError, AttributeError, ImportError, IndexError, TypeError, KeyError) as exc:
        raise damaged(" ".join(f"{type(exc).__name__}: {exc}".split())[:160]) from None
    except OSError as exc:
        raise damaged(exc.strerror or type(exc).__name__) from None
    if not isinstance(payload, dict) or payload.get("format") not in (CHECKPOINT_FORMAT, RL_CHECKPOINT_FORMAT):
        raise damaged("missing or unknown 'format' tag")
    if not isinstance(payload.get("version"), int) or payload["version"] > CHECKPOINT_VERSION:
        raise damaged(
            f"checkpoint version {payload.get('version')!r} is not supported (this newton_lab reads <= "
            f"{CHECKPOINT_VERSION})"
        )
    if not isinstance(payload.get("info"), dict) or not isinstance(payload.get("config"), dict):
        raise damaged("no 'info' or 'config' record")
    return payload
