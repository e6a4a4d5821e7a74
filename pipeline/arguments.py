"""Command-line options made from a technique record's options (jobs/record.py): the flag, the
type and the default come from the option, so the CLI and the panel cannot disagree."""

from __future__ import annotations

import argparse


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
    parser.add_argument(flag, dest=option.dest, type=option.kind, default=default,
                        metavar=option.name.upper(), help=text)


def add_technique_arguments(parser: argparse.ArgumentParser, technique) -> None:
    """Every CLI option of a technique, and its CLI-only switches."""
    for option in technique.all_options():
        if option.cli:
            add_option(parser, option)
    if technique.cli_extra is not None:
        technique.cli_extra(parser)
    if technique.ladder and technique.renders:
        parser.add_argument("--target-error", type=float, default=None, metavar="REL_MSE",
                            help="pick the cheapest settings that reached this relative MSE on the "
                                 "most similar scene `compare` measured (overrides the options)")


def technique_values(technique, argv) -> dict:
    """Option values (and CLI-only switches) of a technique from an argument list."""
    from .run import Parser

    parser = Parser()
    add_technique_arguments(parser, technique)
    args = parser.parse_args(list(argv))
    return {**vars(args), **technique.values_from_args(args)}
