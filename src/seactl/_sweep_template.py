"""The fork server's preload: the template local sweep workers are forked from.

multiprocessing's fork server imports this module once, before it forks the first
worker (:func:`seactl.sweep._start_worker_template`). Every worker then starts with the
sweep's kernels loaded (:func:`seactl._sweep_worker.warm`) and SIGINT ignored. Other
processes this fork server starts inherit both as well.
"""

import signal

from ._sweep_worker import warm

warm()
signal.signal(signal.SIGINT, signal.SIG_IGN)
