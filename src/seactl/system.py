"""The one public system type: :class:`System`, a batch of designs of one block diagram.

Every kind of system (the SEA of :func:`seactl.design`, the rigid actuator of
:func:`seactl.rigid`, a user loop of :func:`seactl.load_loop`) is a subclass that supplies
its diagram, its parameters and its defaults; the views (margins, roots, impedance,
responses, jitter margins, Monte Carlo, exports, runs, sweeps) have the same names, the
same keywords and the same result types for every system.  A view a kind of system
cannot give raises :class:`~seactl.errors.InputError` naming the system and the reason.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from .errors import InputError


class System:
    """A batch of designs of one block diagram, with every analysis as a method.

    Subclasses set the class attributes and implement the views their diagram supports.
    All arrays of a system share its batch ``shape``; ``system[i]`` selects designs (numpy
    indexing), ``len(system)`` is the length of the first batch axis.

    Attributes
    ----------
    kind : str
        ``"sea"``, ``"rigid"`` or ``"loop"``.
    loops : tuple of str
        The names of the delayed loops, the keys of ``delays_ms`` and of the responses'
        ``requested_delays_s`` / ``effective_delays_s``.
    step_unit : str
        Unit of a step amplitude (``"rad"``, ``"m"`` or the loop file's).
    default_step : float
        The step amplitude every front end uses unless told otherwise.
    """

    kind: ClassVar[str] = ""
    loops: ClassVar[tuple[str, ...]] = ()
    step_unit: ClassVar[str] = ""
    default_step: ClassVar[float] = 1.0

    # ------------------------------------------------------------ batch structure
    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        raise NotImplementedError

    def __getitem__(self, idx: Any) -> System:
        raise NotImplementedError

    def __len__(self) -> int:
        if not self.shape:
            raise TypeError(f"len() of a single {type(self).__name__} design")
        return self.shape[0]

    @property
    def size(self) -> int:
        """The number of designs in the batch."""
        return int(np.prod(self.shape))

    def labels(self) -> list[str]:
        """One short legend label per design (flattened batch).

        Returns
        -------
        list of str
            One label per design, in flattened batch order.
        """
        raise NotImplementedError

    def reshape(self, *shape: int) -> System:
        """The same designs with another batch shape.

        Parameters
        ----------
        *shape : int
            New shape (as :meth:`numpy.ndarray.reshape`).

        Returns
        -------
        System
            The same designs, of the same type, with every array reshaped.
        """
        base = self if self.shape else self[None]
        n = base.size
        try:
            idx = np.arange(n).reshape(*shape)
        except (TypeError, ValueError):
            raise InputError("shape", shape, f"integers whose product is {n} (the number of "
                             "designs), one of them -1 at most") from None
        return base[np.unravel_index(idx, base.shape)]

    def unsupported(self, view: str, reason: str) -> InputError:
        """The error a view this kind of system cannot give raises.

        Parameters
        ----------
        view : str
            The method's name.
        reason : str
            Why, and what to use instead.

        Returns
        -------
        InputError
            Naming the system kind and the view.
        """
        return InputError(f"{type(self).__name__}.{view}", self.kind, reason)
