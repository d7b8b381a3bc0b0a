import os
import tempfile

import matplotlib
import pytest

from seactl.apps.cli import main
from seactl.base.usercache import numba_cache_dir

matplotlib.use("Agg")

# Derive block-diagram transfers afresh in every test session (the on-disk cache of
# derived expressions is tested explicitly in test_blockdiagram.py); the compiled kernels
# keep their cache in the user's cache directory (NUMBA_CACHE_DIR takes precedence over
# SEACTL_CACHE_DIR for them), so a session does not compile them all again.
_kernels = numba_cache_dir()
if _kernels is not None:
    os.environ.setdefault("NUMBA_CACHE_DIR", str(_kernels))
os.environ["SEACTL_CACHE_DIR"] = tempfile.mkdtemp(prefix="seactl-test-cache-")
# Commands' progress lines on stderr are tested in test_progress.py (which turns them on);
# the other tests read stderr without them.
os.environ["SEACTL_PROGRESS"] = "off"


def pytest_configure(config):
    # the snapshot is rewritten by a slow test: that option runs the slow tests too
    if config.getoption("--update-claims-snapshot"):
        config.option.markexpr = "not fuzz"


@pytest.fixture(scope="session")
def first_sections_report(tmp_path_factory):
    """The report's first sections (``table-i``, ``feasibility``: seconds, where the whole
    report takes minutes) built once per session through the command line, for the tests
    of the report and of its snapshot."""
    out = tmp_path_factory.mktemp("report") / "seactl-report"
    assert main(["reproduce", "--out", str(out), "--only", "table-i", "--only",
                 "feasibility"]) == 0
    return out


@pytest.fixture(scope="session")
def full_report(tmp_path_factory):
    """The whole report, built once per session through the command line (minutes: for the
    slow tests only)."""
    out = tmp_path_factory.mktemp("report") / "seactl-report"
    assert main(["reproduce", "--out", str(out)]) == 0
    return out


def pytest_addoption(parser):
    parser.addoption("--update-claims-snapshot", action="store_true",
                     help="rewrite tests/data/claims_snapshot.json from a fresh reproduce run")
