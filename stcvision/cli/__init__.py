"""The ``stcvision`` command line: one program, argparse subcommands.

Each subcommand lives in its own module under ``stcvision.cli`` and exposes ``add_parser`` and
``run``. ``run`` imports what it needs lazily (so ``import stcvision`` and ``--help`` stay fast)
and returns a JSON-serialisable dict; with ``--json`` that dict is printed as one JSON object,
otherwise the command's ``format_text`` renders it for people.

Bad input never produces a traceback: a :class:`~stcvision.errors.StcVisionError`, an argparse
usage error or an ``OSError`` about a path becomes one line on stderr and exit code 2 (see
:func:`main` for every exit status).
"""

from __future__ import annotations

import argparse
import errno
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
    ("pipeline", "stcvision.cli.cmd_pipeline", "run the vision pipeline on frames, a video, a camera or a ROS bag"),
    ("cover", "stcvision.cli.cmd_cover", "run the ant-like STC robot until it has covered a board"),
    ("firmware", "stcvision.cli.cmd_firmware", "check the STC controller's C firmware; build it for a microcontroller"),
    ("robot", "stcvision.cli.cmd_robot", "drive an STC robot over a serial link; or be a simulated one on a pty"),
    ("buffon", "stcvision.cli.cmd_buffon", "measure a nest's area blind with Buffon's needle; reproduce the paper"),
    ("search", "stcvision.cli.cmd_search", "run the TASTI 2 chemical-search robot (radial/spiral, obstacle detours)"),
    ("calibrate", "stcvision.cli.cmd_calibrate", "calibrate a camera: dark frames, rim, transformation, neighbours"),
    ("dataset", "stcvision.cli.cmd_dataset", "generate and check labelled frame sets from recipes"),
    ("eval", "stcvision.cli.cmd_eval", "evaluate the pipeline on a dataset or your own frames; compare"),
    ("label", "stcvision.cli.cmd_label", "label your own frames: pipeline proposals on a review sheet"),
    ("bench", "stcvision.cli.cmd_bench", "measure render and pipeline speed on one core"),
]


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line and exit code 2."""

    def error(self, message: str) -> None:  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="stcvision",
        epilog=EXIT_STATUSES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
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
        # a command's description is its module's docstring, whose usage lines and paragraphs are
        # laid out as written: argparse's default formatter would run them into one paragraph
        p = sub.add_parser(
            name, help=help_, description=mod.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
        )
        mod.add_parser(p)
        if not any(a.dest == "json" for a in p._actions) and not getattr(mod, "NESTED", False):
            p.add_argument("--json", action="store_true", help="print the result as one JSON object")
        p.set_defaults(_module=mod)
    return parser


#: exit statuses (docs: What every command guarantees): 0 done; 2 bad input or an output that cannot be made;
#: 3 the command ran but the robot did not complete (cover, demo); 128+N killed by signal N
EXIT_OK, EXIT_BAD_INPUT, EXIT_INCOMPLETE = 0, 2, 3
EXIT_STATUSES = """exit status:
  0    done
  2    bad input, or an output that cannot be made or exists without --force (one line on stderr)
  3    ran, but the robot did not complete (cover, demo: aborted, covered a sub-cell twice, not back)
  130  interrupted (Ctrl-C); 143 SIGTERM; 129 SIGHUP: no partial output but a --rrd recording up to
       the signal (the line says so), no temporary file left
  141  stdout closed early (| head)"""

#: errno values of an OSError that is about a path the user named (one line, exit 2), not a bug
_PATH_ERRNOS = frozenset(
    getattr(errno, n)
    for n in "ENOENT ENOTDIR EISDIR EACCES EPERM EEXIST EROFS ENOSPC EDQUOT ENAMETOOLONG ELOOP EXDEV EFBIG".split()
    if hasattr(errno, n)
)


def _install_signal_handlers() -> dict:
    """Turn SIGTERM and SIGHUP into :class:`Terminated`, and note each Ctrl-C's time before its
    ``KeyboardInterrupt``; returns the handlers they had."""
    import os
    import signal

    from stcvision.errors import Terminated
    from stcvision.fileio import interrupt_received, signal_received

    main_pid = os.getpid()
    previous = {}

    def handler(signum, frame):
        if os.getpid() != main_pid:  # a forked worker: die as the signal says
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        signal_received(signum)  # remembered: a library that swallows the exception cannot commit outputs
        raise Terminated(signum)

    def on_ctrl_c(signum, frame):
        # noted, so that a Ctrl-C whose exception was lost (raised inside a callback from C, as
        # llvmlite's during a numba compile, which ctypes prints and drops) still ends the compile
        if os.getpid() == main_pid:
            interrupt_received()
        raise KeyboardInterrupt

    for sig, h in ((signal.SIGTERM, handler), (signal.SIGHUP, handler), (signal.SIGINT, on_ctrl_c)):
        try:
            if sig == signal.SIGINT and signal.getsignal(sig) is not signal.default_int_handler:
                continue  # Ctrl-C ignored or handled by the caller: left as it is
            previous[sig] = signal.signal(sig, h)
        except (ValueError, OSError):  # not the main thread (main() called from a thread)
            break
    if previous:
        previous["unraisable"] = sys.unraisablehook
        sys.unraisablehook = _quiet_lost_signal(sys.unraisablehook)
    return previous


def _quiet_lost_signal(then):
    """An unraisable-exception hook: a signal's exception that Python could not raise (inside a
    callback from C) is not printed with its traceback, since the signal was noted and the run
    ends on it at the next point that checks (the end of a function's compile, a frame); anything
    else goes to ``then``, the hook in place before."""

    def hook(unraisable) -> None:
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            then(unraisable)

    return hook


def _restore_signal_handlers(previous: dict) -> None:
    import signal

    # Ctrl-C's handler and the hook first: a Ctrl-C while the others are restored is then the
    # default KeyboardInterrupt, and nothing of this run's is left installed
    first = [k for k in ("unraisable", signal.SIGINT) if k in previous]
    for sig in first + [k for k in previous if k not in first]:
        if sig == "unraisable":
            sys.unraisablehook = previous[sig]
        else:
            signal.signal(sig, previous[sig])


def _kept_note() -> str:
    """What an interrupted run kept (its rerun recordings, closed cleanly at the signal), for
    the one line it ends with."""
    from stcvision.fileio import kept_partial

    kept = kept_partial()
    if not kept:
        return ""
    return "; kept " + ", ".join(map(str, kept)) + " as recorded up to the interruption"


def _print_result(args, mod, result) -> None:
    from stcvision.fileio import dumps

    if getattr(args, "json", False):
        print(dumps(result, indent=None))
    else:
        fmt = getattr(mod, "format_text", None)
        print(fmt(result) if fmt else dumps(result))
    sys.stdout.flush()


def _quiet_stdout() -> None:
    """After a broken pipe (``... | head``): point stdout at /dev/null so that the interpreter's
    final flush does not complain (the Python docs' recipe for SIGPIPE)."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``stcvision`` console script; returns the exit code.

    A project error (:class:`~stcvision.errors.StcVisionError`) or an ``OSError`` about a path is
    one line on stderr and exit code 2; a closed stdout (``| head``) ends quietly; SIGINT, SIGTERM
    and SIGHUP end with 128 + the signal's number, leaving no temporary file behind. Any other
    exception is a bug and keeps its traceback.
    """
    from stcvision.errors import Terminated
    from stcvision.fileio import forget_signals, new_run, raise_if_signalled, remove_live_temps

    new_run()
    # the signals are turned into exceptions before the commands' modules are imported: under
    # load their imports take seconds, and a Ctrl-C or SIGTERM then must end the command as one
    # later would, in one line, not with a traceback or the default action's silent death
    previous = _install_signal_handlers()
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt as exc:
        _restore_signal_handlers(previous)
        forget_signals()
        print("stcvision: interrupted", file=sys.stderr)
        return 128 + (exc.signum if isinstance(exc, Terminated) else 2)
    except BaseException:
        _restore_signal_handlers(previous)
        raise
    _restore_signal_handlers(previous)
    if args.command is None:
        parser.print_help()
        return EXIT_BAD_INPUT
    empty = [k for k, v in vars(args).items() if v == "" or (isinstance(v, list) and "" in v)]
    if empty:  # every string this CLI takes is a path or a name: '' is never meant
        flag = (
            empty[0].upper() if empty[0] in ("frames", "frame", "recipe", "dir") else "--" + empty[0].replace("_", "-")
        )
        parser.exit(EXIT_BAD_INPUT, f"stcvision {args.command}: error: {flag} is an empty string; expected a name\n")
    mod = args._module
    name = args.command
    from stcvision.compiles import announce_compiles

    announce_compiles()  # a first run that compiles says so, once, on stderr
    previous = _install_signal_handlers()
    try:
        result = mod.run(args)
        raise_if_signalled()  # a signal whose exception a library swallowed still ends the run
        if isinstance(result, int):
            return result
        if result is None:
            return EXIT_OK
        _print_result(args, mod, result)
    except StcVisionError as exc:
        print(f"stcvision {name}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        _quiet_stdout()
        return 128 + 13  # as a Unix tool killed by SIGPIPE
    except OSError as exc:
        if exc.errno not in _PATH_ERRNOS or exc.filename is None:
            raise
        print(f"stcvision {name}: error: {exc.filename}: {exc.strerror}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, Terminated) else 2
        print(f"stcvision {name}: interrupted{_kept_note()}", file=sys.stderr)
        return 128 + signum
    except Exception as exc:
        # a signal that lands inside code which wraps what it raises (a dataclass's __set_name__
        # during an import turns it into a RuntimeError) still means the user stopped the run
        from stcvision.errors import signal_in_chain

        signum = signal_in_chain(exc)
        if signum is None:
            raise
        print(f"stcvision {name}: interrupted{_kept_note()}", file=sys.stderr)
        return 128 + signum
    finally:
        remove_live_temps()
        forget_signals()
        _restore_signal_handlers(previous)
    return int(result.get("exit_code", EXIT_OK)) if isinstance(result, dict) else EXIT_OK
