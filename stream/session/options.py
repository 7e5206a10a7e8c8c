"""Command-line options declared once, on the configuration's fields, and generated for every command.

A configuration dataclass (``TrackingConfig``, ``MeasureConfig``) declares each option on its field with
``option(default, help=...)``: its flag, metavar, argparse type and help live there, next to the default and
the validation. ``add_config_arguments`` adds them to a command's parser, with the defaults (``run``,
``measure``) or without (``replay``: unset means the recorded value, and the shorter ``brief`` help is shown);
``config_values`` reads them back from the parsed arguments. The commands: docs/guide/commands.md.
"""

from __future__ import annotations

import argparse
from dataclasses import MISSING, Field, dataclass, field, fields
from typing import Any, Callable

_NUMBER_TYPES: dict[Any, Callable[[str], Any]] = {int: int, float: float, "int": int, "float": float}


@dataclass(frozen=True)
class Option:
    """How one configuration field appears on the command line.

    ``help`` and ``brief`` may name ``{default}``; ``brief`` (default: ``help``) is shown where there is no
    default of the configuration's own (replay: the recorded value). ``type`` converts and checks the text
    (default: ``int``/``float`` by the field's type); ``action`` e.g. ``"store_false"`` for a ``--no-x`` flag.
    """
    help: str
    brief: str | None = None
    metavar: str | None = None
    type: Callable[[str], Any] | None = None
    flag: str | None = None
    action: str | None = None


def option(default: Any, help: str, **how: Any) -> Any:
    """A dataclass field with ``default`` that is also a command-line option (``Option(help, **how)``)."""
    return field(default=default, metadata={"option": Option(help, **how)})


def option_fields(config: type) -> list[Field]:
    """The fields of the dataclass ``config`` that are command-line options, in declaration order."""
    return [f for f in fields(config) if "option" in f.metadata]


def flag_of(f: Field) -> str:
    """``--seed-radius`` for the field ``seed_radius`` (or the option's own flag)."""
    return f.metadata["option"].flag or "--" + f.name.replace("_", "-")


def add_config_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup, config: type, *,
                         with_defaults: bool = True, names: tuple[str, ...] | None = None) -> None:
    """Add ``config``'s options (those in ``names`` only, if given) to ``parser``.

    ``with_defaults``: the configuration's defaults, and the full help; False: no default (None: the caller
    fills it, e.g. from a recording) and the ``brief`` help.
    """
    for f in option_fields(config):
        if names is not None and f.name not in names:
            continue
        how: Option = f.metadata["option"]
        default = f.default if f.default is not MISSING else None
        text = how.help if with_defaults else (how.brief or how.help)
        kwargs: dict[str, Any] = {"dest": f.name, "help": text.format(default=default)}
        if how.action is not None:
            kwargs["action"] = how.action
        else:
            kwargs["type"] = how.type or _NUMBER_TYPES.get(f.type)
            kwargs["metavar"] = how.metavar
        if with_defaults:
            kwargs["default"] = default
        elif how.action is not None:
            kwargs["default"] = None
        parser.add_argument(flag_of(f), **kwargs)


def config_values(config: type, args: argparse.Namespace, *, given_only: bool = False) -> dict[str, Any]:
    """``config``'s option values from parsed ``args``; ``given_only``: only those set (not None)."""
    values = {f.name: getattr(args, f.name) for f in option_fields(config) if hasattr(args, f.name)}
    return {name: value for name, value in values.items() if value is not None} if given_only else values
