import os
import tempfile

import matplotlib

from seactl.usercache import numba_cache_dir

matplotlib.use("Agg")

# Derive block-diagram transfers afresh in every test session (the on-disk cache of
# derived expressions is tested explicitly in test_blockdiagram.py); the compiled kernels
# keep their cache in the user's cache directory (NUMBA_CACHE_DIR takes precedence over
# SEACTL_CACHE_DIR for them), so a session does not compile them all again.
_kernels = numba_cache_dir()
if _kernels is not None:
    os.environ.setdefault("NUMBA_CACHE_DIR", str(_kernels))
os.environ["SEACTL_CACHE_DIR"] = tempfile.mkdtemp(prefix="seactl-test-cache-")


def pytest_addoption(parser):
    parser.addoption("--update-claims-snapshot", action="store_true",
                     help="rewrite tests/data/claims_snapshot.json from a fresh reproduce run")
