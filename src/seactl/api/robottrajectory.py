"""A robot's trajectory read from a CSV file: :func:`read_trajectory`.

The file has a header of joint names (every joint of the robot once, in any order) and
optionally a time column ``t_s`` [s]; below it one row per sample, joint angles in
radians.  The angles come back in the robot's joint order.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from seactl.errors import InputError

TIME_COLUMN = "t_s"
"""The optional time column [s]."""


def read_trajectory(path: str | Path, joints: Sequence[str]
                    ) -> tuple[np.ndarray, np.ndarray | None]:
    """The joint angles (and times) of a trajectory file.

    Parameters
    ----------
    path : str or path
        A CSV file: a header of joint names and optionally ``t_s``, one row per sample.
    joints : sequence of str
        The robot's joints (the order of the result's columns).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray or None)
        ``(m, n)`` angles [rad] and the ``(m,)`` times [s] (None without ``t_s``).

    Raises
    ------
    InputError
        An unreadable file, a header that is not the robot's joints, a row of the wrong
        length, a value that is not a finite number, or no rows; one line each.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "traj.csv"
    >>> _ = p.write_text("t_s,j2,j1\\n0,0.8,0.3\\n0.01,0.9,0.3\\n")
    >>> q, t = read_trajectory(p, ["j1", "j2"])
    >>> q.tolist(), t.tolist()
    ([[0.3, 0.8], [0.3, 0.9]], [0.0, 0.01])
    """
    from seactl.base.outputs import note_input

    name = str(path)
    try:
        with open(path, newline="") as fh:
            rows = [r for r in csv.reader(fh) if r and any(x.strip() for x in r)]
        note_input(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError("trajectory", name, f"a readable CSV file ({exc})") from None
    if not rows:
        raise InputError("trajectory", name, "a CSV file with a header of joint names")
    header = [h.strip() for h in rows[0]]
    order = _columns(name, header, list(joints))
    values = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:]):
        values[i] = _row(name, i + 2, row, header)
    if values.shape[0] == 0:
        raise InputError("trajectory", name, "at least one row of joint angles below the "
                         "header")
    t = values[:, header.index(TIME_COLUMN)] if TIME_COLUMN in header else None
    return values[:, order], t


def _columns(name: str, header: list[str], joints: list[str]) -> list[int]:
    """The header's column of each joint; the header must name every joint once (and
    ``t_s`` at most once)."""
    unknown = [h for h in header if h not in joints and h != TIME_COLUMN]
    if unknown:
        raise InputError("trajectory", name, f"a header of the robot's joints "
                         f"({', '.join(joints)}) and optionally {TIME_COLUMN}; unknown "
                         f"column(s): {', '.join(repr(u) for u in unknown)}")
    twice = sorted({h for h in header if header.count(h) > 1})
    missing = [j for j in joints if j not in header]
    if twice or missing:
        what = (f"repeated: {', '.join(twice)}" if twice else
                f"missing: {', '.join(missing)}")
        raise InputError("trajectory", name, f"a header naming each joint once "
                         f"({', '.join(joints)}); {what}")
    return [header.index(j) for j in joints]


def _row(name: str, line: int, row: list[str], header: list[str]) -> list[float]:
    """The numbers of one row (``line``: its line in the file)."""
    if len(row) != len(header):
        raise InputError("trajectory", name, f"{len(header)} values per row (the header's "
                         f"columns); line {line} has {len(row)}")
    try:
        out = [float(x) for x in row]
    except ValueError:
        out = [math.nan]
    if not all(math.isfinite(x) for x in out):
        raise InputError("trajectory", name, f"finite numbers; line {line} is "
                         f"{','.join(x.strip() for x in row)!r}")
    return out
