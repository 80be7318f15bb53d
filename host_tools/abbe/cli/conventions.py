"""Conventions every ``abbe`` command follows, applied once to the whole parser tree.

* List options take several values and may be repeated: ``--ballbar a b`` and
  ``--ballbar a --ballbar b`` both give ``[a, b]`` (``nargs="+"`` with
  ``action="extend"``; :func:`list_option`).
* A single-valued option given twice is an error (exit 2), never a silent
  "the last one wins" (a user who repeats an option expects both to count).
* ``abbe COMMAND --help`` ends with example lines (:func:`examples`), printed as
  written; descriptions are wrapped.
"""

from __future__ import annotations

import argparse
from typing import Any, Iterator


def examples(*lines: str) -> str:
    """The ``epilog`` of a command: its example command lines."""
    return ("examples:\n" if len(lines) > 1 else "example:\n") + "\n".join(
        "  " + line for line in lines)


def list_option(parser: argparse.ArgumentParser, *flags: str, **kwargs: Any) -> argparse.Action:
    """Add a list option that accepts ``--opt a b`` and ``--opt a --opt b``."""
    return parser.add_argument(*flags, nargs="+", action="extend", **kwargs)


class HelpFormatter(argparse.HelpFormatter):
    """Wraps descriptions; prints the examples epilog line by line as written."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if text.startswith(("example:\n", "examples:\n")):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


class _StoreOnce(argparse._StoreAction):
    """A single-valued option that refuses to be given twice."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        seen = namespace.__dict__.setdefault("_abbe_options_seen", set())
        if self.dest in seen:
            parser.error(f"{'/'.join(self.option_strings)} given more than once "
                         "(it takes one value)")
        seen.add(self.dest)
        super().__call__(parser, namespace, values, option_string)


def walk(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
         ) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """Every parser of the tree with its command path (``("table", "eval")``)."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from walk(sub, path + (name,))


def apply(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Apply the conventions to every parser of the tree (after all commands registered)."""
    for _path, p in walk(parser):
        p.formatter_class = HelpFormatter
        for action in p._actions:
            if type(action) is argparse._StoreAction and action.option_strings:
                action.__class__ = _StoreOnce
    return parser


def clean(args: argparse.Namespace) -> argparse.Namespace:
    """Drop the bookkeeping attribute :class:`_StoreOnce` leaves on the namespace."""
    args.__dict__.pop("_abbe_options_seen", None)
    return args
