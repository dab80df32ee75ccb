"""Argument parsing helpers shared by the subcommands (one-line errors, units in names)."""

from __future__ import annotations

import argparse
import math


def _number(kind: type, text: str):
    """``kind(text)``, finite; ValueError otherwise (argparse turns it into one line)."""
    v = kind(text)
    if kind is float and not math.isfinite(v):
        raise ValueError(text)
    return v


def pair(kind: type = float, n: int = 2, *, fmt: str | None = None, example: str | None = None):
    """argparse type for ``A,B`` (or ``AxB``) tuples of ``n`` finite numbers; ``fmt`` names the
    form in the message (e.g. ``WxH``) and ``example`` shows one."""
    names = {int: "integers", float: "finite numbers"}[kind]
    example = example or ",".join(["1"] * n)
    form = f"{fmt} ({n} {names}, e.g. {example})" if fmt else f"{n} comma-separated {names} (e.g. {example})"

    def parse(text: str) -> tuple:
        parts = text.replace("x", ",").split(",")
        try:
            if len(parts) != n:
                raise ValueError
            return tuple(_number(kind, p) for p in parts)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {form}") from None

    return parse


def positive(kind: type = float, *, maximum: float | None = None, why: str = ""):
    """argparse type for a strictly positive, finite number, at most ``maximum`` when given (a cap
    on the work a flag can ask for; ``why`` says what it bounds)."""

    def parse(text: str):
        try:
            v = _number(kind, text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a finite {_kind_name(kind)}") from None
        if not v > 0:
            raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
        if maximum is not None and v > maximum:
            raise argparse.ArgumentTypeError(f"{text!r} is over the cap of {maximum:,}" + (f" ({why})" if why else ""))
        return v

    return parse


def seed(text: str) -> int:
    """argparse type for a seed: an integer >= 0 (numpy's SeedSequence takes no negative seed)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 0")
    return v


def _kind_name(kind: type) -> str:
    return {int: "integer", float: "number"}[kind]
