"""Argument parsing helpers shared by the subcommands (one-line errors, units in names)."""

from __future__ import annotations

import argparse


def pair(kind: type = float, n: int = 2):
    """argparse type for ``A,B`` (or ``AxB``) tuples of ``n`` numbers."""

    def parse(text: str) -> tuple:
        parts = text.replace("x", ",").split(",")
        try:
            if len(parts) != n:
                raise ValueError
            return tuple(kind(p) for p in parts)
        except ValueError:
            names = {int: "integers", float: "numbers"}[kind]
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {n} comma-separated {names} (e.g. {','.join(['1'] * n)})"
            ) from None

    return parse


def positive(kind: type = float):
    """argparse type for a strictly positive number."""

    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not v > 0:
            raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
        return v

    return parse
