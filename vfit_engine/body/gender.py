"""A body's gender as people write it: "female", "male" (or f, m) or a blend 0..1 (0 female, 1 male).

Imports nothing but the standard library, so the CLI's option type can use it before ``--help``.
"""
import math


def parse_gender(value):
    """"female", "male" or a float in 0..1 from ``value`` (any case); ValueError saying what is wrong."""
    text = str(value).strip().lower()
    if text in ("female", "f", "male", "m"):
        return "female" if text.startswith("f") else "male"
    try:
        x = float(text)
    except ValueError:
        raise ValueError(f"{value!r} is not female, male or a number in 0..1") from None
    if not (math.isfinite(x) and 0.0 <= x <= 1.0):
        raise ValueError(f"{value!r} is not in 0..1")
    return x
