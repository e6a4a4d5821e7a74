"""Command-line options made from a technique record's options (jobs/record.py): the flag, the
type and the default come from the option, so the CLI and the panel cannot disagree."""

from __future__ import annotations

import argparse
import math

from .outputs import UsageError


class Parser(argparse.ArgumentParser):
    """argparse that raises UsageError instead of printing usage and exiting."""

    def error(self, message):
        raise UsageError(message)


def finite_float(text: str) -> float:
    """argparse type of every float option: a number, never nan or inf (which would run a whole
    bake and then fail writing metrics.json, or silently give a black or empty result)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type of a finite number above 0 (a budget)."""
    value = finite_float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be above 0, got {text!r}")
    return value


def non_empty(text: str) -> str:
    """argparse type of a name that must not be empty (a UV layer name)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    return text


def pixels(text: str) -> int:
    """argparse type of one side of an image in pixels: an integer in [1, 16384]."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 1 <= value <= 16384:
        raise argparse.ArgumentTypeError(f"resolution must be in [1, 16384], got {value}")
    return value


def tile_part(text: str):
    """argparse type of `--tile`: K/N or 'prepare' (jobs/tiles.py)."""
    from ..jobs.tiles import parse_tile

    try:
        return parse_tile(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def option_type(option):
    """The argparse type of a record option: floats finite, names non-empty where the default
    is (an empty default means "none" and stays allowed), others as they are."""
    if option.kind is float:
        return finite_float
    if option.kind is str and option.default:
        return non_empty
    return option.kind


def _choice_help(option) -> str:
    return "; ".join(f"{value}: {description}" for value, _label, description in option.choices)


def add_option(parser: argparse.ArgumentParser, option) -> None:
    """One record option as an argparse argument. Booleans: `--NAME` when off by default,
    `--no-NAME` when on. Ranges are checked by the settings dataclasses (one message)."""
    flag, default = option.cli_flag(), option.default
    if option.kind is bool:
        if default:
            parser.add_argument("--no-" + flag[2:], dest=option.dest, action="store_false",
                                help=f"{option.help} (on by default; this turns it off)")
        else:
            parser.add_argument(flag, dest=option.dest, action="store_true", help=option.help)
        return
    text = f"{option.help} (default {default})"
    if option.choices:
        parser.add_argument(flag, dest=option.dest, choices=[c[0] for c in option.choices],
                            default=default, help=f"{text}. {_choice_help(option)}")
        return
    parser.add_argument(flag, dest=option.dest, type=option_type(option), default=default,
                        metavar=option.name.upper(), help=text)


def add_technique_arguments(parser: argparse.ArgumentParser, technique) -> None:
    """Every CLI option of a technique, and its CLI-only switches."""
    for option in technique.all_options():
        if option.cli:
            add_option(parser, option)
    if technique.cli_extra is not None:
        technique.cli_extra(parser)
    if technique.tiles:
        parser.add_argument("--tile", type=tile_part, default=None, metavar="K/N",
                            help=f"bake part K of N (1-based) of the {technique.tiles} into "
                                 "OUT/tiles/, for `merge OUT` to put together"
                                 + ("; 'prepare': the part every tile needs first"
                                    if technique.tile_prepare else ""))
    if technique.ladder and technique.renders:
        parser.add_argument("--target-error", type=finite_float, default=None, metavar="REL_MSE",
                            help="pick the cheapest settings that reached this relative MSE on the "
                                 "most similar scene `compare` measured (overrides the options)")


def technique_values(technique, argv) -> dict:
    """Option values (and CLI-only switches) of a technique from an argument list."""
    parser = Parser()
    add_technique_arguments(parser, technique)
    args = parser.parse_args(list(argv))
    return {**vars(args), **technique.values_from_args(args)}
