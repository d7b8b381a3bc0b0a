"""The fork server's preload: the template local sweep workers are forked from.

multiprocessing's fork server imports this module once, before it forks the first
worker (:func:`seactl.sweep.engine.start_worker_template`); importing is all a preload can
do. In that server, and only there, the import calls :func:`prepare`: seactl starts the
server with :data:`seactl.sweep.spec.TEMPLATE_MARKER` in its environment, which the server then
drops (its children do not carry it). Every worker then starts with the sweep's kernels
loaded (:func:`seactl.sweep.worker.warm`) and SIGINT ignored; other processes this fork
server starts inherit both as well. Imported anywhere else (pytest's doctest collection,
``help()``), the module only defines things.
"""

import os
import signal

from seactl.sweep.spec import TEMPLATE_MARKER
from seactl.sweep.worker import warm


def prepare() -> None:
    """Make this process the workers' template: the sweep's kernels loaded, SIGINT
    ignored."""
    warm()
    signal.signal(signal.SIGINT, signal.SIG_IGN)


if os.environ.pop(TEMPLATE_MARKER, None) == "1":
    prepare()
