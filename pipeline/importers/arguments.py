"""Number arguments of the importers' command lines, checked when argparse reads them."""

from __future__ import annotations

import argparse
import math


def finite(text: str) -> float:
    """Return ``text`` as a finite float; an argparse error otherwise."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"'{text}' is not a finite number")
    return value


def positive(text: str) -> float:
    """Return ``text`` as a finite float above 0; an argparse error otherwise."""
    value = finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number above 0")
    return value


def non_negative(text: str) -> float:
    """Return ``text`` as a finite float of at least 0; an argparse error otherwise."""
    value = finite(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"'{text}' is negative")
    return value
