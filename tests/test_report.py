"""The reproduction report: claims, determinism, atomic writes."""

import json

import pytest

from seactl.apps import paper, report, report_page
from seactl.apps.cli import main

# The paper's Table I typed here (f_n -> K_q, B_q, K_tau, B_tau, PM) and half a unit of each
# printed digit (the PM column is truncated: 43.26 is printed 43.2)
TABLE_I = {12: (65, 0.46, 1.18, 0.057, 45.1), 14: (83, 0.76, 1.80, 0.067, 43.2),
           16: (103, 1.02, 2.56, 0.077, 40.0), 18: (124, 1.26, 3.45, 0.087, 36.5),
           20: (148, 1.49, 4.48, 0.097, 33.2)}
HALF_DIGIT = (0.5, 0.005, 0.005, 0.0005, 0.1)


def test_table_i_section(first_sections_report):
    """Oracle: the paper's Table I typed in this file, against both the claims' paper values
    (the transcription in seactl.apps.paper) and our values."""
    out = first_sections_report  # (conftest: table-i and feasibility)
    claims = json.loads((out / "claims.json").read_text())
    by_id = {c["id"]: c for c in claims}
    for f, printed in TABLE_I.items():
        for k, paper_value, half in zip(("Kq", "Bq", "Ktau", "Btau", "PM"), printed, HALF_DIGIT):
            c = by_id[f"table1.fn{f}.{k}"]
            assert c["paper_value"] == pytest.approx(paper_value), c
            assert c["our_value"] == pytest.approx(paper_value, abs=half + 1e-9), c
            assert c["status"] == "pass", c
    for c in claims:
        assert set(c) >= {"id", "section", "claim", "paper_value", "our_value", "tolerance",
                          "status"}
    assert "Table I" in (out / "index.html").read_text()


@pytest.mark.slow  # (the gain-scale section alone takes tens of seconds)
def test_gain_scale_section(tmp_path, capsys):
    """Oracle: Fig. GainScale(a) of the paper, typed here, against the claims' paper
    values and our values."""
    out = tmp_path / "rep"
    assert main(["reproduce", "--out", str(out), "--only", "gain-scale"]) == 0
    by_id = {c["id"]: c for c in json.loads((out / "claims.json").read_text())}
    gs04 = by_id["gainscale.gs0.4_fn14"]
    assert gs04["paper_value"] == pytest.approx(34.0)
    assert gs04["our_value"] == pytest.approx(34.0, abs=0.1) and gs04["status"] == "pass"
    # GS = 1 is not the exact optimum at f_n = 14 Hz: reported, not hidden (the optimum's
    # location against a dense scan: tests/test_report_numbers.py)
    c14 = by_id["gainscale.gs1_max.fn14"]
    assert c14["status"] == "fail" and "GS = 0.779" in c14["note"]
    assert c14["our_value"] == pytest.approx(0.78, abs=0.005)
    assert (out / "figures" / "gain_scale.png").stat().st_size > 1000
    assert "gain_scale.png" in (out / "index.html").read_text()


def test_claims_json_is_byte_identical(tmp_path, capsys):
    # Oracle: a second run's bytes.
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        assert main(["reproduce", "--out", str(d), "--only", "table-i"]) == 0
    assert (a / "claims.json").read_bytes() == (b / "claims.json").read_bytes()


def test_interrupted_run_leaves_previous_report_intact(tmp_path, monkeypatch, capsys):
    # Oracle: the previous report's bytes and the directory listing.
    out = tmp_path / "rep"
    assert main(["reproduce", "--out", str(out), "--only", "table-i"]) == 0
    before = (out / "claims.json").read_bytes()

    def boom(ctx):
        raise KeyboardInterrupt

    boom.section_id = "boom"
    monkeypatch.setattr(paper, "SECTIONS", paper.SECTIONS + (boom,))
    with pytest.raises(KeyboardInterrupt):
        paper.reproduce(out, only=["table-i", "boom"], jobs=1)
    assert (out / "claims.json").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]  # no temp leftovers


def test_sections_in_worker_processes_equal_the_serial_run(tmp_path):
    # Oracle: the same sections run one after the other in this process.
    only = ["table-i", "feasibility"]
    a = paper.reproduce(tmp_path / "a", only=only, jobs=1)
    b = paper.reproduce(tmp_path / "b", only=only, jobs=2)
    assert a == b
    assert (tmp_path / "a" / "claims.json").read_bytes() == \
        (tmp_path / "b" / "claims.json").read_bytes()


def test_a_section_failing_in_a_worker_stops_the_run_cleanly(tmp_path, monkeypatch):
    # Oracle: the exception raised in the worker, the directory listing, and no child left.
    import functools
    import multiprocessing
    import operator

    boom = functools.partial(operator.truediv, 1, 0)  # picklable; any call raises
    boom.section_id = "boom"
    monkeypatch.setattr(paper, "SECTIONS", paper.SECTIONS + (boom,))
    with pytest.raises(TypeError):
        paper.reproduce(tmp_path / "rep", only=["table-i", "boom"], jobs=2)
    assert list(tmp_path.iterdir()) == []
    assert multiprocessing.active_children() == []


def test_unknown_section_is_an_input_error(tmp_path, capsys):
    # Oracle: the CLI error contract (exit 2).
    assert main(["reproduce", "--out", str(tmp_path / "x"), "--only", "nope"]) == 2


@pytest.mark.parametrize("value, tol, unit, text", [
    (65.16832287, 1.0, "Nm/rad", "65.2 Nm/rad"),      # one digit finer than the tolerance
    (43.2641, 0.1, "deg", "43.26 deg"),
    (0.000123456, None, "", "0.0001235"),              # no numeric tolerance: 4 digits
    ([True, False, True], "equal", "", "2 of 3 yes"),
    (None, None, "", "n/a"),
    (float("nan"), 1.0, "", "nan"),
])
def test_claim_values_are_formatted_for_people(value, tol, unit, text):
    # Oracle: the strings typed by hand in the table above.
    assert report_page.format_value(value, tol, unit) == text


def test_summary_lists_every_claim_that_is_not_a_pass(tmp_path, monkeypatch):
    """Oracle: claims.json of the same run (Table I's passing claims, and a section with a
    passing, a failing and an informative claim)."""
    def mixed(ctx):
        sec = report.Section("mixed", "Mixed")
        for i, status in enumerate(("pass", "fail", "info")):
            sec.claims.append(report.Claim(f"mixed.c{i}", "Mixed", f"claim {i}", 1.0, 2.0,
                                           0.5, status))
        return sec

    mixed.section_id = "mixed"
    monkeypatch.setattr(paper, "SECTIONS", paper.SECTIONS + (mixed,))
    out = tmp_path / "rep"
    paper.reproduce(out, only=["table-i", "mixed"], jobs=1)
    claims = json.loads((out / "claims.json").read_text())
    html = (out / "index.html").read_text()
    summary = html[html.index('id="summary"'):html.index('<section id="', html.index(
        'id="summary"') + 1)]
    flagged = [c["id"] for c in claims if c["status"] != "pass"]
    assert flagged == ["mixed.c1", "mixed.c2"]
    assert all(f'href="#claim-{i}"' in summary for i in flagged)
    assert all(f'href="#claim-{c["id"]}"' not in summary for c in claims
               if c["status"] == "pass")
    assert all(f'id="claim-{c["id"]}"' in html for c in claims)


def test_running_section_without_a_run_fails_its_claims(tmp_path, monkeypatch):
    """Oracle: the section's own claim ids; a run that cannot start (here forced) makes
    both claims fail with the reason in the text, and the report is still written."""
    from seactl.apps.paper import running
    from seactl.codegen import runtime
    from seactl.errors import SeactlError

    def cannot(*args, **kwargs):
        raise SeactlError("run: process 'plant' failed (zenoh): no route")

    monkeypatch.setattr(runtime, "run_distributed", cannot)
    sec = running.running(report.Context(tmp_path))
    assert [c.id for c in sec.claims] == ["running-replay", "running-delivery"]
    assert all(c.status == "fail" for c in sec.claims) and "no route" in sec.intro
