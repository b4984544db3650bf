"""Flags from the argument dataclasses (``newton_lab.commands``): fields -> flags, field docstrings -> help.

A field ``num_envs`` is the flag ``--num-envs``; ``bool`` fields are switches; ``X | None`` fields are optional;
fields without a default are required; ``list`` fields take one or more values; field metadata may set ``flags``
or ``positional``; the ``task_options`` field becomes one flag per option any task declares.
"""

from __future__ import annotations

import argparse
import dataclasses
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Any, Literal

from ..task_api.catalog import all_declared_options
from .help_text import REQUIRED, field_docs, help_of


def _unwrap_optional(tp: Any) -> Any:
    if isinstance(tp, types.UnionType) or typing.get_origin(tp) is typing.Union:
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return tp


def _type_kwargs(tp: Any, default: Any) -> dict[str, Any]:
    """argparse keywords for a field of type ``tp`` whose default is ``default``."""
    tp = _unwrap_optional(tp)
    origin = typing.get_origin(tp)
    if tp is bool:
        return {"action": argparse.BooleanOptionalAction if default is True else "store_true"}
    if origin is Literal:
        return {"choices": list(typing.get_args(tp))}
    if origin in (list, tuple):
        return {"nargs": "+", "type": typing.get_args(tp)[0]}
    if tp in (int, float, str):
        return {"type": tp}
    raise TypeError(f"no command-line form for a field of type {tp!r}")


def _fields(cls: type, exclude: Iterable[str]) -> list[dataclasses.Field]:
    skip = set(exclude)
    unknown = skip - {f.name for f in dataclasses.fields(cls)}
    if unknown:
        raise ValueError(f"{cls.__name__} has no field(s) {sorted(unknown)}")
    return [f for f in dataclasses.fields(cls) if f.name not in skip]


def add_arguments(
    parser: argparse.ArgumentParser,
    cls: type,
    *,
    defaults: Mapping[str, Any] | None = None,
    exclude: Iterable[str] = (),
    choices: Mapping[str, Iterable[Any]] | None = None,
) -> None:
    """One argument per field of dataclass ``cls`` (in field order), except the ``exclude``d ones."""
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    defaults, choices = dict(defaults or {}), dict(choices or {})
    for f in _fields(cls, exclude):
        if f.metadata.get("task_options"):
            add_task_option_flags(parser)
            continue
        default = defaults.get(f.name, f.default)
        kwargs = _type_kwargs(hints[f.name], default)
        if f.name in choices:
            kwargs["choices"] = list(choices[f.name])
        if doc := docs.get(f.name):
            kwargs["help"] = help_of(doc)
        if f.metadata.get("positional"):
            parser.add_argument(f.name, **kwargs)
            continue
        if default is REQUIRED:
            kwargs["required"] = True
        else:
            kwargs["default"] = default
        flags = f.metadata.get("flags", ("--" + f.name.replace("_", "-"),))
        parser.add_argument(*flags, dest=f.name, **kwargs)


TASK_OPTION_DEST = "task_option:"
"""Namespace prefix of the task-option flags."""


def add_task_option_flags(parser: argparse.ArgumentParser) -> None:
    """One flag per option any task declares (``--sorting-object``), read from the task packages' source
    (``newton_lab.task_api.catalog``): a new option of a task becomes a flag without touching the command line.
    Literal choices are offered in the help; whether the chosen task takes the option is checked with the rest
    of the arguments (``check_args``)."""
    for name, opt in sorted(all_declared_options().items()):
        help_text = help_of(opt.doc or f"task option {name}")
        if opt.choices:
            help_text += f" (one of: {', '.join(opt.choices)})"
        parser.add_argument("--" + name.replace("_", "-"), dest=TASK_OPTION_DEST + name, default=None, help=help_text)


def from_namespace(cls: type, ns: argparse.Namespace, *, defaults: Mapping[str, Any] | None = None):
    """``cls`` from parsed arguments; fields argparse did not see take ``defaults`` or their own default. The
    task-option flags that were given fill the ``task_options`` field."""
    values = {k: v for k, v in (defaults or {}).items() if v is not REQUIRED}
    values.update({f.name: getattr(ns, f.name) for f in dataclasses.fields(cls) if hasattr(ns, f.name)})
    for f in dataclasses.fields(cls):
        if f.metadata.get("task_options"):
            given = {
                k[len(TASK_OPTION_DEST) :]: v
                for k, v in vars(ns).items()
                if k.startswith(TASK_OPTION_DEST) and v is not None
            }
            values[f.name] = {**values.get(f.name, {}), **given}
    return cls(**values)
