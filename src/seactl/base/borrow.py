"""Arrays without reference counts, for the compiled kernels' inner loops.

Numba counts the references of every array that a compiled function passes to another
one it does not inline: two atomic (``lock``-prefixed) instructions per array per call.
In the margin scan, which calls its per-point and per-interval helpers some hundred
times per design with half a dozen arrays each, those counts would cost more than much of
the arithmetic they guard.

:func:`borrowed` gives a view of an array whose memory-info pointer is null, so that its
counts are no-ops (numba's ``NRT_incref`` returns at once on a null pointer).  The view
does not keep the array alive, so a kernel borrows only its own arguments, which its
caller holds for the whole call (numba may release a kernel's local array right after
its last use, which would be the ``borrowed`` call), and never returns a borrowed view.
"""

from __future__ import annotations

from numba.extending import intrinsic
from numba.np.arrayobj import populate_array


@intrinsic
def borrowed(typingctx, arr):  # pragma: no cover - compiled
    """A view of ``arr`` (same data, shape and strides) that numba does not count
    references of; valid only while ``arr`` is alive (see the module docstring)."""

    def codegen(context, builder, sig, args):
        src = context.make_array(sig.args[0])(context, builder, args[0])
        view = context.make_array(sig.return_type)(context, builder)
        populate_array(view, data=src.data, shape=src.shape, strides=src.strides,
                       itemsize=src.itemsize, meminfo=None)
        return view._getvalue()

    return arr(arr), codegen
