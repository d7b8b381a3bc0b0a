"""A :class:`~seactl.codegen.parametric.Program` as a pure-Python class (``<process>.py``),
the same algorithm and parameter semantics as the C (in double precision)."""

from __future__ import annotations

import math

from seactl.codegen.parametric import Program, render


def _lit(x: float) -> str:
    x = float(x)
    if math.isinf(x):
        return "math.inf" if x > 0 else "-math.inf"
    return repr(x)


def class_name(ident: str) -> str:
    return "".join(w[:1].upper() + w[1:] for w in ident.split("_") if w) or "Process"


_CLASS = '''

class @CLASS:
    """Process @NAME: ``step(inputs, fresh=True) -> outputs`` at RATE_HZ.

    ``params`` (a dict, the C ``params`` struct) may be changed between two calls with
    ``set_params``: the states are kept (bumpless); ``reset()`` zeroes them."""

    RATE_HZ = @RATE
    INPUTS = @INPUTS
    OUTPUTS = @OUTPUTS
    COMMANDS = @COMMANDS
    DEFAULT_PARAMS = @DEFAULTS
    SIGNALS = @NS
    PERIOD_S = @PERIOD
    # per block: source, destination, order, buffer length, message output (-1: none)
    BLOCKS = @BLOCKS
    INPUT_SIGNAL = @IN_SIG
    OUTPUT_SIGNAL = @OUT_SIG
    LIMITS = @LIMITS

    def __init__(self, params=None):
        self.init(params)

    def init(self, params=None):
        self.params = None
        if self.set_params(dict(self.DEFAULT_PARAMS, **(params or {}))) != 0:
            raise ValueError("parameters refused (non-finite coefficients or a singular "
                             "network)")
        self.reset()

    def reset(self):
        """Zero every state, buffer and the watchdog's count; the parameters stay."""
        self.w = [[0.0] * b[2] for b in self.BLOCKS]
        self.buf = [[0.0] * b[3] for b in self.BLOCKS]
        self.head = [0] * len(self.BLOCKS)
        self.age = 0
        self.watchdog = False

    @staticmethod
    def _coeffs(prm):
@COEFFS

    @staticmethod
    def _tustin(n, cs, T):
        out = [0.0] * (n + 1)
        wj = 1.0
        for j in range(n + 1):
            p = [1.0]
            for k in range(n):
                sgn = -1.0 if k < j else 1.0
                p = p + [0.0]
                for i in range(len(p) - 1, 0, -1):
                    p[i] += sgn * p[i - 1]
            for i in range(n + 1):
                out[i] += cs[n - j] * wj * p[i]
            wj *= 2.0 / T
        return out

    def set_params(self, params):
        """Use ``params`` from the next call (0), or refuse them and keep the old (-1)."""
        prm = dict(params)
        nums, dens = self._coeffs(prm)
        bz, az, d = [], [], []
        for (src, dst, q, nbuf, msg), cn, cd in zip(self.BLOCKS, nums, dens):
            b, a = self._tustin(q, cn, self.PERIOD_S), self._tustin(q, cd, self.PERIOD_S)
            if not a[0] != 0.0 or not all(math.isfinite(x) for x in b + a):
                return -1
            bz.append(b)
            az.append(a)
            d.append(b[0] / a[0])
        g = self._inverse(d)
        if g is None:
            return -1
        self.params, self.bz, self.az, self.d, self.g = prm, bz, az, d, g
        return 0

    def _inverse(self, d):
        n = self.SIGNALS
        a = [[float(i == j) for j in range(n)] for i in range(n)]
        inv = [[float(i == j) for j in range(n)] for i in range(n)]
        for (src, dst, q, nbuf, msg), db in zip(self.BLOCKS, d):
            if nbuf == 0:
                a[dst][src] -= db
        for k in range(n):
            piv = max(range(k, n), key=lambda i: abs(a[i][k]))
            if not a[piv][k] != 0.0:
                return None
            a[k], a[piv] = a[piv], a[k]
            inv[k], inv[piv] = inv[piv], inv[k]
            t = a[k][k]
            a[k] = [x / t for x in a[k]]
            inv[k] = [x / t for x in inv[k]]
            for i in range(n):
                t = a[i][k]
                if i == k or t == 0.0:
                    continue
                a[i] = [x - t * y for x, y in zip(a[i], a[k])]
                inv[i] = [x - t * y for x, y in zip(inv[i], inv[k])]
        if not all(math.isfinite(x) for row in inv for x in row):
            return None
        return inv

    def step(self, inputs, fresh=True):
        """One call: ``inputs`` maps every name of INPUTS to a float; ``fresh``: the
        commands (COMMANDS) were refreshed since the last call."""
        n = self.SIGNALS
        r = [0.0] * n
        for name, sig in zip(self.INPUTS, self.INPUT_SIGNAL):
            r[sig] += float(inputs[name])
        f, u = [], []
        for b, (src, dst, q, nbuf, msg) in enumerate(self.BLOCKS):
            bz, az, w, db = self.bz[b], self.az[b], self.w[b], self.d[b]
            fr = 0.0
            for i in range(1, q + 1):
                fr += (bz[i] - db * az[i]) * w[i - 1]
            f.append(fr)
            if nbuf:
                u.append(self.buf[b][self.head[b]])
                r[dst] += db * u[b] + fr
            else:
                u.append(0.0)
                r[dst] += fr
        s = []
        for row in self.g:
            acc = 0.0
            for gij, rj in zip(row, r):
                acc += gij * rj
            s.append(acc)
        y = [s[k] if k >= 0 else 0.0 for k in self.OUTPUT_SIGNAL]
        for b, (src, dst, q, nbuf, msg) in enumerate(self.BLOCKS):
            if not nbuf:
                u[b] = s[src]
            if msg >= 0:
                y[msg] += self.d[b] * u[b] + f[b]
            if q:
                az, w = self.az[b], self.w[b]
                wn = u[b]
                for i in range(1, q + 1):
                    wn -= az[i] * w[i - 1]
                w.insert(0, wn / az[0])
                w.pop()
            if nbuf:
                self.buf[b][self.head[b]] = s[src]
                self.head[b] = (self.head[b] + 1) % nbuf
        self.age = 0 if fresh else self.age + 1
        limit = self.params["watchdog_ticks"]
        self.watchdog = limit > 0 and self.age > limit
        out = {}
        for i, (name, lim) in enumerate(zip(self.OUTPUTS, self.LIMITS)):
            v = y[i] if lim is None else min(max(y[i], -self.params[lim]), self.params[lim])
            out[name] = 0.0 if self.watchdog else v
        return out
'''


def source(prog: Program, banner: str) -> str:
    """``<process>.py``."""
    sym = lambda n: f"prm[{n!r}]"  # noqa: E731
    nums = ", ".join("[" + ", ".join(render(c, sym, _lit) for c in b.num) + "]"
                     for b in prog.blocks)
    dens = ", ".join("[" + ", ".join(render(c, sym, _lit) for c in b.den) + "]"
                     for b in prog.blocks)
    coeffs = (f"        return [{nums}], \\\n            [{dens}]")
    defaults = dict(prog.parameters)
    defaults.update({lim[0]: lim[1] for lim in prog.limits if lim})
    defaults["watchdog_ticks"] = prog.watchdog_ticks
    text = "{" + ", ".join(f"{k!r}: {_lit(v) if isinstance(v, float) else v}"
                           for k, v in defaults.items()) + "}"
    blocks = tuple((b.src, b.dst, b.order, b.buffer, b.message) for b in prog.blocks)
    subs = {"@CLASS": class_name(prog.ident), "@NAME": repr(prog.name),
            "@RATE": _lit(prog.rate_hz), "@INPUTS": repr(tuple(prog.inputs)),
            "@OUTPUTS": repr(tuple(prog.outputs)), "@COMMANDS": repr(tuple(prog.commands)),
            "@DEFAULTS": text, "@NS": str(len(prog.signals)),
            "@PERIOD": _lit(1.0 / prog.rate_hz), "@BLOCKS": repr(blocks),
            "@IN_SIG": repr(tuple(prog.input_signal)),
            "@OUT_SIG": repr(tuple(prog.output_signal)),
            "@LIMITS": repr(tuple(lim[0] if lim else None for lim in prog.limits)),
            "@COEFFS": coeffs}
    body = _CLASS
    for k, v in subs.items():
        body = body.replace(k, v)
    return banner + "import math\n" + body
