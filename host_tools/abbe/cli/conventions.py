"""Conventions every ``abbe`` command follows, applied once to the whole parser tree.

* List options take several values and may be repeated: ``--ballbar a b`` and
  ``--ballbar a --ballbar b`` both give ``[a, b]`` (``nargs="+"`` with
  ``action="extend"``; :func:`list_option`).
* A single-valued option given twice is an error (exit 2), never a silent
  "the last one wins" (a user who repeats an option expects both to count).
* ``abbe COMMAND --help`` ends with example lines (:func:`examples`), printed as
  written; descriptions are wrapped.
* ``--json FILE`` writes the command's JSON document to FILE (atomically, beside any
  text the command prints); ``--json -`` prints it on stdout instead of the text, so
  stdout holds one JSON document (:func:`json_option`). The bare ``--json`` of
  abbe 0.1.0 (print JSON) still works for one release and says on stderr that it is
  deprecated. A FILE that exists and does not end in ``.json`` is refused: a bare
  ``--json`` written before a positional argument (``abbe iso230-2 --json x.csv``)
  would otherwise take the measurement file as the output (docs/cli.md).
* Every command that evaluates writes an output folder ``-o DIR`` that
  ``abbe history add`` reads.
"""

from __future__ import annotations

import argparse
from typing import Any, Iterator


def examples(*lines: str) -> str:
    """The ``epilog`` of a command: its example command lines."""
    return ("examples:\n" if len(lines) > 1 else "example:\n") + "\n".join(
        "  " + line for line in lines)


#: ``--json -``: the JSON document goes to stdout.
STDOUT = "-"
_BARE = object()  # the deprecated bare ``--json``


def json_option(parser: argparse.ArgumentParser, what: str = "") -> argparse.Action:
    """Add ``--json FILE`` (``-`` for stdout); ``what`` names the document in the help."""
    return parser.add_argument("--json", metavar="FILE", nargs="?", const=_BARE,
                               action=_JsonAction,
                               help=f"write {what or 'the JSON document'} to FILE ('-': print "
                                    "it on stdout instead of the text; docs/cli.md)")


def list_option(parser: argparse.ArgumentParser, *flags: str, **kwargs: Any) -> argparse.Action:
    """Add a list option that accepts ``--opt a b`` and ``--opt a --opt b``."""
    return parser.add_argument(*flags, nargs="+", action="extend", **kwargs)


class HelpFormatter(argparse.HelpFormatter):
    """Wraps descriptions; prints the examples epilog line by line as written."""

    def _format_args(self, action: argparse.Action, default_metavar: str) -> str:
        if isinstance(action, _JsonAction):  # the bare form is deprecated: not advertised
            return "FILE"
        return super()._format_args(action, default_metavar)

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


class _JsonAction(_StoreOnce):
    """``--json FILE`` / ``--json -``; the bare ``--json`` (deprecated) means ``-``."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        if values is _BARE:
            namespace.__dict__.setdefault("_abbe_deprecations", []).append(
                "--json without a FILE is deprecated and goes in the next release: write "
                "'--json -' to print the JSON on stdout, or '--json FILE' (docs/cli.md)")
            values = STDOUT
        elif values != STDOUT:
            from pathlib import Path
            p = Path(values)
            if p.suffix.lower() != ".json" and p.is_file():
                parser.error(f"--json {values}: that file "
                             "exists and is not a .json file; --json takes the FILE to write "
                             "(or '-' for stdout): put a bare --json last, or write --json -")
        super().__call__(parser, namespace, values, option_string)


def json_to_stdout(args: argparse.Namespace) -> bool:
    """True when the JSON document replaces the text on stdout (``--json -``)."""
    return getattr(args, "json", None) == STDOUT


def json_file(args: argparse.Namespace) -> str | None:
    """The FILE of ``--json FILE`` (None for stdout or no --json)."""
    v = getattr(args, "json", None)
    return None if v in (None, STDOUT) else str(v)


def print_json(doc: Any) -> None:
    """The JSON document on stdout (``--json -``): finite numbers only."""
    import json
    import sys
    json.dump(doc, sys.stdout, indent=2, allow_nan=False)
    sys.stdout.write("\n")


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


def clean(args: argparse.Namespace, prog: str = "abbe") -> argparse.Namespace:
    """Drop the bookkeeping attributes the actions leave on the namespace; say the
    deprecated forms used on stderr (once each)."""
    import sys
    args.__dict__.pop("_abbe_options_seen", None)
    if getattr(args, "command", None):
        prog = f"{prog} {args.command}"
    for msg in dict.fromkeys(args.__dict__.pop("_abbe_deprecations", [])):
        print(f"{prog}: warning: {msg}", file=sys.stderr)
    return args
