"""Reading the tables rich draws: their columns, and the numeric ones without a unit."""

from __future__ import annotations

import re

NUMBER = re.compile(r"[-+]?(\d[\d,]*\.?\d*|\.\d+)(e[-+]?\d+)?")
DIMENSIONLESS = {"GS", "ratio", "ratio d/s", "worst run", "messages", "points", "states",
                 "RHP roots", "min sigma(I+L)"}
"""Numeric columns whose numbers have no unit: gain scales, ratios, counts, run indices."""


def table_columns(text: str) -> list[tuple[str, list[str]]]:
    """(header, body cells) of every column of every table rich drew in ``text``."""
    cols: list[tuple[str, list[str]]] = []
    head: list[list[str]] = []
    body: list[list[str]] = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("┃"):
            head.append([c.strip() for c in s.strip("┃").split("┃")])
        elif s.startswith("│") and head:
            body.append([c.strip() for c in s.strip("│").split("│")])
        elif s.startswith("└") and head:
            for j in range(len(head[0])):
                cols.append((" ".join(h[j] for h in head if h[j]),
                             [r[j] for r in body if len(r) == len(head[0]) and r[j]]))
            head, body = [], []
    return cols


def _numeric(cell: str) -> bool:
    return bool(NUMBER.fullmatch(cell.split(" (")[0]))


def _named(header: str) -> bool:
    return ("[" in header or header in DIMENSIONLESS
            or bool(re.search(r"_(hz|s|ms|deg|db|rad|m)$", header)))


def unitless_numeric_columns(text: str) -> list[str]:
    """Numeric columns without a unit; in a quantity / value table, the quantities whose
    value is a number without one."""
    cols = table_columns(text)
    bad = []
    for k, (h, cells) in enumerate(cols):
        if h == "value" and k and cols[k - 1][0] == "quantity":
            bad += [q for q, v in zip(cols[k - 1][1], cells)
                    if _numeric(v) and not _named(q) and not q.startswith("P(")]
        elif any(_numeric(c) for c in cells) and not _named(h):
            bad.append(h)
    return bad
