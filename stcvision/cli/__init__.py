"""The ``stcvision`` command line: one program, argparse subcommands.

Each subcommand lives in its own module under ``stcvision.cli`` and exposes ``add_parser`` and
``run``. ``run`` imports what it needs lazily (so ``import stcvision`` and ``--help`` stay fast)
and returns a JSON-serialisable dict; with ``--json`` that dict is printed as one JSON object,
otherwise the command's ``format_text`` renders it for people.

Bad input never produces a traceback: a :class:`~stcvision.errors.StcVisionError` (or an argparse
usage error) becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from stcvision import __version__
from stcvision.errors import StcVisionError

# (name, module, one-line help). Order = order in --help.
COMMANDS: list[tuple[str, str, str]] = [
    ("demo", "stcvision.cli.cmd_demo", "run the toolkit's main job on an embedded default"),
    ("world", "stcvision.cli.cmd_world", "build an arena or board world, drive a robot, draw it"),
    ("render", "stcvision.cli.cmd_render", "render a synthetic catadioptric frame with ground truth"),
    ("pipeline", "stcvision.cli.cmd_pipeline", "run the vision pipeline on frames from disk"),
    ("cover", "stcvision.cli.cmd_cover", "run the ant-like STC robot until it has covered a board"),
    ("buffon", "stcvision.cli.cmd_buffon", "measure a nest's area blind with Buffon's needle; reproduce the paper"),
    ("search", "stcvision.cli.cmd_search", "run the TASTI 2 chemical-search robot (radial/spiral, obstacle detours)"),
    ("calibrate", "stcvision.cli.cmd_calibrate", "calibrate a camera: dark frames, rim, transformation, neighbours"),
    ("dataset", "stcvision.cli.cmd_dataset", "generate and check labelled frame sets from recipes"),
    ("eval", "stcvision.cli.cmd_eval", "evaluate the pipeline on a dataset or your own frames; compare"),
    ("bench", "stcvision.cli.cmd_bench", "measure render and pipeline speed on one core"),
]


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line and exit code 2."""

    def error(self, message: str) -> None:  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="stcvision",
        description=(
            "Toolkit for robots that mark a phosphorescent floor with UV LEDs and read the marks "
            "back through a catadioptric camera: vision pipeline, simulator, controllers, "
            "calibration."
        ),
    )
    parser.add_argument("--version", action="version", version=f"stcvision {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, module, help_ in COMMANDS:
        mod = importlib.import_module(module)
        p = sub.add_parser(name, help=help_, description=mod.__doc__)
        mod.add_parser(p)
        if not any(a.dest == "json" for a in p._actions) and not getattr(mod, "NESTED", False):
            p.add_argument("--json", action="store_true", help="print the result as one JSON object")
        p.set_defaults(_module=mod)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``stcvision`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    mod = args._module
    try:
        result = mod.run(args)
    except StcVisionError as exc:
        print(f"stcvision {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"stcvision {args.command}: interrupted", file=sys.stderr)
        return 130
    if isinstance(result, int):
        return result
    if result is None:
        return 0
    from stcvision.fileio import dumps

    if getattr(args, "json", False):
        print(dumps(result, indent=None))
    else:
        fmt = getattr(mod, "format_text", None)
        print(fmt(result) if fmt else dumps(result))
    return int(result.get("exit_code", 0)) if isinstance(result, dict) else 0
