"""MkDocs hook: the command-line reference, generated from the argparse parsers themselves.

``docs/reference/cli.md`` holds the marker ``<!-- cli-reference -->``; at build time it is
replaced by every command's and sub-command's ``--help`` text, taken from
``stcvision.cli.build_parser()``. The options are therefore written once, in the parsers, and the
site cannot disagree with ``stcvision COMMAND --help``.
"""

from __future__ import annotations

import argparse
import os

MARKER = "<!-- cli-reference -->"
#: help is wrapped at this width on the page (argparse reads COLUMNS)
WIDTH = "100"


def _subcommands(parser: argparse.ArgumentParser):
    """(name, parser) of each sub-command of ``parser``, in the order --help lists them."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            seen = set()
            for name, sub in action.choices.items():
                if id(sub) not in seen:  # aliases point at the same parser
                    seen.add(id(sub))
                    yield name, sub


def _walk(parser: argparse.ArgumentParser, path: tuple[str, ...]):
    yield path, parser
    for name, sub in _subcommands(parser):
        yield from _walk(sub, (*path, name))


def cli_reference_markdown() -> str:
    """Markdown of every command's help: one section per command, sub-commands beneath."""
    from stcvision.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        parts = []
        for path, parser in _walk(build_parser(), ("stcvision",)):
            level = "#" * min(len(path) + 1, 4)
            parts.append(f"{level} `{' '.join(path)}`\n\n```text\n{parser.format_help().rstrip()}\n```\n")
        return "\n".join(parts)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 - the MkDocs hook API
    if MARKER in markdown:
        return markdown.replace(MARKER, cli_reference_markdown())
    return markdown
