"""Keyword options to the command line's flags, so that the command line's own parser reads
them (same defaults, checks and messages).

``dead_time="estimate"`` → ``--dead-time=estimate``; ``True`` → ``--flag``; ``False`` and
``None`` → omitted; a list or tuple → the flag repeated; a dict → ``NAME=VALUE`` items
(``fix={"r_s": 0.9, "k_e": None}`` → ``--fix=r_s=0.9 --fix=k_e``), or ``NAME:LO:HI`` for a
pair (``bounds={"r_s": (0.1, 5)}``); underscores in names become hyphens.
"""

from __future__ import annotations

import os
from typing import Any, Iterable, Mapping

__all__ = ["to_argv"]


def _word(value: Any) -> str:
    """One value as the command line writes it (floats in their shortest exact form)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def _items(value: Mapping[str, Any]) -> Iterable[str]:
    for name, v in value.items():
        if v is None:
            yield str(name)
        elif isinstance(v, (tuple, list)):
            yield ":".join([str(name), *(_word(x) for x in v)])
        else:
            yield f"{name}={_word(v)}"


def to_argv(options: Mapping[str, Any], positional: Iterable[str] = ()) -> list[str]:
    """The flags of ``options`` (in their order), then ``--`` and the ``positional`` words.

    Every value is attached with ``=`` (``--huber=2.0``, ``--from=-0.5``), which every flag
    accepts and which keeps a negative number from reading as a flag.
    """
    argv: list[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            argv.append(flag)
        elif isinstance(value, Mapping):
            argv.extend(f"{flag}={item}" for item in _items(value))
        elif isinstance(value, (list, tuple)):
            argv.extend(f"{flag}={_word(v)}" for v in value)
        else:
            argv.append(f"{flag}={_word(value)}")
    words = list(positional)
    if words:
        argv.append("--")
        argv.extend(words)
    return argv
