"""The help text of the flags: a field's docstring (read from its dataclass's source) as its help, and the
formatter that shows every option's default."""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import re
import textwrap

REQUIRED = dataclasses.MISSING
"""A ``defaults`` value making a field required (an example that needs ``--checkpoint``)."""


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions kept as written; every option with a default shows it (``(default: ...)``) unless its
    help already says its default; switches and unset optionals show none."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            "%(default)" in text
            or "default" in text.lower()
            or not action.option_strings
            or any(default is x for x in (None, False, argparse.SUPPRESS, REQUIRED))
            or action.required
        ):
            return text
        return f"{text} (default: %(default)s)"


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """The docstring under each field of dataclass ``cls`` (own or inherited; the nearest class wins)."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        try:
            source = textwrap.dedent(inspect.getsource(klass))
        except (OSError, TypeError):
            continue
        body = ast.parse(source).body[0].body
        for stmt, nxt in zip(body, body[1:]):
            if (
                isinstance(stmt, ast.AnnAssign)
                and isinstance(stmt.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                docs[stmt.target.id] = " ".join(nxt.value.value.split())
    return docs


def help_of(doc: str) -> str:
    """A field docstring as argparse help: reST literals as plain backticks, ``%`` escaped."""
    return re.sub(r"``([^`]*)``", r"`\1`", doc).replace("%", "%%")
