"""The reproduction report: sections, claims, figures, HTML, written atomically.

A *section* is a function ``f(ctx) -> Section`` tagged with :func:`section`;
the sections of the paper, and their order, live in :mod:`seactl.apps.paper`, which
imports this module (never the reverse).  Each returns prose, tables, figures
and :class:`Claim` objects comparing a number of the paper with the value
seactl computes.  :func:`build` runs a list of sections,
writes ``figures/*.png``, ``claims.json`` and ``index.html`` into a temporary
directory next to the target and renames it into place at the end, so an
interrupted run never leaves a half report.  The page itself (its words, the
verdict per section, the HTML) is :mod:`seactl.apps.report_page`.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from seactl.apps.report_page import render_html
from seactl.base import progress
from seactl.base.outputs import reason
from seactl.errors import OutputError

STATUSES = ("pass", "fail", "info", "skip")


@dataclass(frozen=True)
class Claim:
    """A numeric claim of the paper and what seactl computes for it.

    ``status`` is ``pass`` when ``|our - paper| <= tolerance`` (numbers) or
    the stated relation holds, ``fail`` otherwise (``note`` says why),
    ``info`` for findings without a pass/fail criterion, and ``skip`` for a claim
    not computed here (``note`` says why, e.g. an optional extra not installed).
    """

    id: str
    section: str
    claim: str
    paper_value: Any
    our_value: Any
    tolerance: Any
    status: str
    note: str = ""

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")

    def as_json(self) -> dict[str, Any]:
        d = asdict(self)
        for key in ("paper_value", "our_value", "tolerance"):
            d[key] = _clean(d[key])
        if not d["note"]:
            d.pop("note")
        return d


def pm_cell(pm_deg: float, stable: bool, spec: str = ".1f") -> str:
    """A phase margin for a report table, marked when the design is unstable (the margin
    of one crossover says nothing once a closed-loop root is in the right half-plane)."""
    text = format(float(pm_deg), spec) if np.isfinite(pm_deg) else "none"
    return text if stable else f"{text} (unstable)"


def numeric_claim(id: str, section: str, claim: str, paper: float, ours: float,
                  tol: float, note: str = "") -> Claim:
    """A claim that passes when ``|ours - paper| <= tol``."""
    ok = math.isfinite(ours) and abs(ours - paper) <= tol
    if not ok and not note:
        note = f"differs by {ours - paper:+.4g} (tolerance {tol:g})"
    return Claim(id, section, claim, paper, ours, tol, "pass" if ok else "fail", note)


def _clean(v: Any) -> Any:
    """JSON-stable values: floats rounded to 10 significant digits, NaN/inf as strings."""
    if isinstance(v, np.generic):
        v = v.item()
    elif isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        return float(f"{v:.10g}")
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    return v


@dataclass
class Figure:
    filename: str   # relative to figures/
    caption: str


@dataclass
class Section:
    """One section of the report."""

    id: str
    title: str
    intro: str = ""
    tables: list[tuple[str, list[str], list[list[str]]]] = field(default_factory=list)
    figures: list[Figure] = field(default_factory=list)
    claims: list[Claim] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Context:
    """What a section gets: where to save figures."""

    figures_dir: Path

    def savefig(self, fig: Any, name: str) -> str:
        """Save a matplotlib figure as ``figures/name`` and close it; returns ``name``."""
        import matplotlib.pyplot as plt

        fig.savefig(self.figures_dir / name, dpi=110, bbox_inches="tight")
        plt.close(fig)
        return name


SectionFn = Callable[[Context], Section]


def section(order: int, id: str) -> Callable[[SectionFn], SectionFn]:
    """Tag a report section builder with its id (``order`` is kept for readers; the order of
    the report is the explicit list in :data:`seactl.apps.paper.SECTIONS`)."""

    def deco(func: SectionFn) -> SectionFn:
        func.section_id = id  # type: ignore[attr-defined]
        func.section_order = order  # type: ignore[attr-defined]
        return func

    return deco


@dataclass(frozen=True)
class KernelWarmup:
    """Work that compiles kernel ``groups`` (:mod:`seactl.base.jit`, defined in
    ``modules``) and no other: ``run`` is a module-level function (it runs in a worker
    process).  On a cold cache :func:`build` runs the warm-ups side by side before the
    sections, so no two workers compile the same kernels."""

    groups: tuple[str, ...]
    modules: tuple[str, ...]
    run: Callable[[], Any]
    sections: tuple[str, ...] = ()
    """Ids of sections that need no kernel of the other warm-ups: queued right behind
    this one, so a worker done compiling early runs them while the others compile."""

    def cold(self) -> bool:
        """Whether a group of it has nothing in the kernel cache (imports ``modules``)."""
        import importlib

        from seactl.base import jit

        for m in self.modules:
            importlib.import_module(m)
        return any(jit.is_cold(g) for g in self.groups)


def build(out: Path, sections: Iterable[SectionFn], jobs: int = 1,
          warmups: Iterable[KernelWarmup] = (), first: Iterable[str] = ()
          ) -> list[dict[str, Any]]:
    """Run ``sections`` and write the report into ``out`` (atomically); return the claims.
    ``jobs > 1`` runs the sections in that many worker processes (they are independent;
    the report keeps their order), after the ``warmups`` whose kernels are not cached yet,
    the sections named in ``first`` (the longest, longest first: the workers then finish
    close together) before the others.  Progress goes to :mod:`seactl.base.progress`."""
    import matplotlib

    matplotlib.use("Agg")

    sections = list(sections)
    out = Path(out).absolute()
    check_report_dir(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    except OSError as exc:
        raise OutputError(out, reason(exc)) from None
    try:
        os.chmod(tmp, 0o777 & ~_umask())
        (tmp / "figures").mkdir()
        ctx = Context(tmp / "figures")
        if jobs > 1 and len(sections) > 1:
            built = _run_parallel(sections, ctx, min(jobs, len(sections)), list(warmups),
                                  list(first))
        else:
            built = _run_serial(sections, ctx)
        claims = [c.as_json() for s in built for c in s.claims]
        (tmp / "claims.json").write_text(json.dumps(claims, indent=2, sort_keys=True) + "\n")
        (tmp / "index.html").write_text(_render(built, claims))
        write_marker(tmp)
        _swap_into_place(tmp, out)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(out, reason(exc)) from None
        raise
    return claims


def _sections_stage(n: int) -> Any:
    return progress.stage("reproducing the paper", total=n, unit="sections")


def _run_serial(sections: list[SectionFn], ctx: Context) -> list[Section]:
    built = []
    with _sections_stage(len(sections)) as stage:
        for func in sections:
            built.append(func(ctx))
            stage.advance(item=func.section_id)
    return built


def _quiet_worker() -> None:
    """Report workers leave Ctrl-C to the parent (which stops them): no tracebacks."""
    import signal

    import matplotlib

    from seactl.base import parallel as _parallel

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    matplotlib.use("Agg")
    _parallel.THREADS = 1  # (one worker per core already)


def _warm(pool: Any, warmups: list[KernelWarmup], jobs: int, ctx: Context,
          sections: list[SectionFn]) -> dict[SectionFn, Any]:
    """The cold ``warmups`` side by side in ``pool``, each followed by its own
    :attr:`~KernelWarmup.sections`, announced as one stage; returns those sections'
    futures."""
    from concurrent.futures import FIRST_COMPLETED, wait

    from seactl.base import jit

    cold = [w for w in warmups if w.cold()]
    if not cold:
        return {}
    names = list(dict.fromkeys(g for w in cold for g in w.groups))
    about = sum(jit.kernel_group(g).about_s for g in names) / min(jobs, len(cold))
    jit.said(names)
    progress.note(f"compiling the {', '.join(names)} kernels in {jobs} processes (once per "
                  f"installation, about {progress.duration_text(about)})")
    by_id = {f.section_id: f for f in sections}
    with progress.stage("compiling kernels", total=len(cold), unit="groups",
                        expected_s=about) as stage:
        groups, early = {}, {}
        for w in cold:
            groups[pool.submit(w.run)] = ", ".join(w.groups)
            early |= {by_id[i]: pool.submit(by_id[i], ctx) for i in w.sections if i in by_id}
        pending = set(groups)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                f.result()
                stage.advance(item=groups[f])
    return early


def _run_parallel(sections: list[SectionFn], ctx: Context, jobs: int,
                  warmups: list[KernelWarmup], first: list[str]) -> list[Section]:
    """The sections in ``jobs`` fresh ("spawn") processes, results in report order; any
    failure or Ctrl-C stops every worker."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    rank = {sid: k for k, sid in enumerate(first)}
    queue = sorted(sections, key=lambda f: rank.get(f.section_id, len(rank)))  # (stable)
    pool = ProcessPoolExecutor(jobs, multiprocessing.get_context("spawn"),
                               initializer=_quiet_worker)
    try:
        futures = _warm(pool, warmups, jobs, ctx, queue)
        with _sections_stage(len(sections)) as stage:
            futures |= {f: pool.submit(f, ctx) for f in queue if f not in futures}
            ids = {fut: f.section_id for f, fut in futures.items()}
            pending = set(ids)
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    fut.result()  # raises the section's error here
                    stage.advance(item=ids[fut])
        return [futures[f].result() for f in sections]
    except BaseException:
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.terminate()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


MARKER = ".seactl-report"
"""File that marks a directory as a report seactl wrote: its first line says so, the
others list every file and directory seactl wrote there (relative, ``/``-separated)."""
MARKER_HEADER = "written by seactl reproduce; seactl may replace the files listed below"
LEGACY_FILES = ("index.html", "claims.json", "figures")
"""What a marker without a list (the older format) stands for, with the
``.png`` figures in ``figures/``."""


def write_marker(tmp: Path) -> None:
    """The marker of the report in ``tmp``, listing everything in it."""
    names = sorted(p.relative_to(tmp).as_posix() for p in tmp.rglob("*"))
    (tmp / MARKER).write_text("\n".join([MARKER_HEADER, *names]) + "\n")


def _written_by_seactl(out: Path) -> set[str]:
    lines = (out / MARKER).read_text(errors="replace").splitlines()
    if lines[:1] == [MARKER_HEADER]:
        return {MARKER, *lines[1:]}
    return {MARKER, *LEGACY_FILES, *(f"figures/{p.name}" for p in out.glob("figures/*.png"))}


def check_report_dir(out: Path) -> None:
    """Refuse ``out`` unless it is absent, an empty directory, or a report seactl wrote
    that holds nothing else (replacing it must not delete a file a user added)."""
    out = Path(out)
    if not out.exists():
        return
    if not out.is_dir():
        raise OutputError(out, "exists and is not a directory")
    if not any(out.iterdir()):
        return
    if not (out / MARKER).is_file():
        raise OutputError(out, "the directory is not empty and is not a report seactl wrote "
                          "(choose a new or empty directory)")
    try:
        ours = _written_by_seactl(out)
        foreign = sorted(rel for p in out.rglob("*")
                         if (rel := p.relative_to(out).as_posix()) not in ours)
    except OSError as exc:
        raise OutputError(out, reason(exc)) from None
    if foreign:
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise OutputError(out, f"it holds {foreign[0]}{more}, which seactl did not write "
                          "(move it out, or choose a new or empty directory)")


def _swap_into_place(tmp: Path, out: Path) -> None:
    """Replace ``out`` by ``tmp`` with renames only (never a half-written ``out``)."""
    check_report_dir(out)
    old = None
    if out.exists():
        old = out.with_name(f".{out.name}.old-{os.getpid()}")
        os.replace(out, old)
    os.replace(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _render(sections: list[Section], claims: list[dict[str, Any]]) -> str:
    from importlib.metadata import version

    return render_html(sections, claims, version("seactl"))
