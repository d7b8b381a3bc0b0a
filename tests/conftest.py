import os
import tempfile

import matplotlib

matplotlib.use("Agg")

# Derive block-diagram transfers afresh in every test session (the on-disk cache of
# derived expressions is tested explicitly in test_blockdiagram.py).
os.environ["SEACTL_CACHE_DIR"] = tempfile.mkdtemp(prefix="seactl-test-cache-")


def pytest_addoption(parser):
    parser.addoption("--update-claims-snapshot", action="store_true",
                     help="rewrite tests/data/claims_snapshot.json from a fresh reproduce run")
