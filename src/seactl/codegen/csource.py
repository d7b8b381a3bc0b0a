"""A :class:`~seactl.codegen.parametric.Program` as C99: ``<process>.h``, ``<process>.c``
and the CSV harness ``<process>_main.c``.

The C holds no dynamic memory (every array is in the state struct, sized at export) and
calls no library function (``<math.h>`` only for ``HUGE_VAL``); the parameters live in a
struct the caller may change between two calls of ``step`` (``<process>_set_params``).
``real`` is ``double`` or ``float`` (the signals, states and outputs); the coefficients
are computed in ``double``.
"""

from __future__ import annotations

import math

from seactl.codegen.controllers import c_ident
from seactl.codegen.parametric import Program, render

REALS = ("double", "float")


def _lit(x: float) -> str:
    """Exact C literal of a double (shortest repr round-trips); HUGE_VAL for infinity."""
    x = float(x)
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "(-HUGE_VAL)"
    if not math.isfinite(x):
        raise ValueError(f"non-finite value {x!r}")
    return repr(x)


def _ints(values: list[int] | tuple[int, ...]) -> str:
    return "{" + ", ".join(str(int(v)) for v in (values or [0])) + "}"


def _sizes(prog: Program) -> dict[str, int]:
    blocks = prog.blocks
    return {"NS": len(prog.signals), "NB": len(blocks), "NI": len(prog.inputs),
            "NO": len(prog.outputs), "NW": sum(b.order for b in blocks),
            "NC": sum(b.order + 1 for b in blocks), "NBUF": sum(b.buffer for b in blocks),
            "MAXN": prog.max_order}


def header(prog: Program, banner: str, real: str) -> str:
    """``<process>.h``: the parameter, state, inputs and outputs structs and the API."""
    p, P = prog.ident, prog.ident.upper()
    z = {k: max(v, 1) for k, v in _sizes(prog).items()}
    params = [f"    double {n}; /* default {v!r} */" for n, v in prog.parameters.items()]
    params += [f"    double {lim[0]}; /* |{o}| <= this (HUGE_VAL: none) */"
               for o, lim in zip(prog.outputs, prog.limits) if lim]
    params.append(f"    long watchdog_ticks; /* default {prog.watchdog_ticks}; <= 0: off */")
    ins = [f"    {p}_real {c_ident(n)};" for n in prog.inputs] or ["    char unused;"]
    outs = [f"    {p}_real {c_ident(n)};" for n in prog.outputs] + [
        "    int watchdog; /* 1: no fresh command for more than watchdog_ticks calls; "
        "the outputs are zero */"]
    return (banner + f"#ifndef SEACTL_{P}_H\n#define SEACTL_{P}_H\n\n"
            f"typedef {real} {p}_real;\n\n"
            f"#define {P}_RATE_HZ {_lit(prog.rate_hz)}\n"
            + "".join(f"#define {P}_{k} {v}\n" for k, v in z.items()) + "\n"
            "typedef struct {\n" + "\n".join(params) + f"\n}} {p}_params;\n\n"
            "typedef struct {\n"
            f"    {p}_params prm;                /* the parameters in use */\n"
            f"    double bz[{P}_NC], az[{P}_NC];  /* discrete coefficients */\n"
            f"    {p}_real d[{P}_NB], f[{P}_NB], u[{P}_NB];\n"
            f"    {p}_real g[{P}_NS * {P}_NS];    /* (I - F)^-1 */\n"
            f"    double work[2 * {P}_NS * {P}_NS]; /* set_params's workspace */\n"
            f"    {p}_real w[{P}_NW];             /* block states */\n"
            f"    {p}_real buf[{P}_NBUF];         /* emulated latency (if any) */\n"
            f"    int head[{P}_NB];\n"
            f"    {p}_real r[{P}_NS], s[{P}_NS];\n"
            "    long age;                       /* calls since the last fresh command */\n"
            f"}} {p}_state;\n\n"
            "typedef struct {\n" + "\n".join(ins) + f"\n}} {p}_inputs;\n\n"
            "typedef struct {\n" + "\n".join(outs) + f"\n}} {p}_outputs;\n\n"
            f"void {p}_default_params({p}_params *prm);\n"
            f"int {p}_set_params({p}_state *s, const {p}_params *prm);\n"
            f"void {p}_reset({p}_state *s);\n"
            f"void {p}_init({p}_state *s);\n"
            f"void {p}_step({p}_state *s, const {p}_inputs *in, int fresh, "
            f"{p}_outputs *out);\n\n"
            f"#endif /* SEACTL_{P}_H */\n")


def _coeffs(prog: Program) -> list[str]:
    """``cn``/``cd``: each block's continuous coefficients from the parameters."""
    body, k = [], 0
    sym = lambda n: f"prm->{n}"  # noqa: E731
    for b in prog.blocks:
        for i in range(b.order + 1):
            body.append(f"    cn[{k + i}] = {render(b.num[i], sym, _lit)};")
            body.append(f"    cd[{k + i}] = {render(b.den[i], sym, _lit)};")
        k += b.order + 1
    return body


def _tables(prog: Program) -> str:
    p, bl = prog.ident, prog.blocks
    coef, hist, buf = [], [], []
    for _b in bl:
        coef.append(sum(x.order + 1 for x in bl[:len(coef)]))
        hist.append(sum(x.order for x in bl[:len(hist)]))
        buf.append(sum(x.buffer for x in bl[:len(buf)]))
    rows = {"src": [b.src for b in bl], "dst": [b.dst for b in bl],
            "ord": [b.order for b in bl], "coef": coef, "hist": hist, "buf": buf,
            "len": [b.buffer for b in bl], "msg": [b.message for b in bl],
            "in_sig": list(prog.input_signal), "out_sig": list(prog.output_signal)}
    text = "".join(f"static const int {p}_{k}[] = {_ints(v)};\n" for k, v in rows.items())
    return text + f"static const double {p}_T = {_lit(1.0 / prog.rate_hz)};\n"


_BODY = """
/* (z-1)^j (z+1)^(n-j) summed with weights c_j (2/T)^j: the bilinear transform of the
   polynomial with coefficients cs (highest power of s first), highest power of z first */
static void @_tustin(int n, const double *cs, double *out)
{
    double p[@P_MAXN + 1], wj = 1.0;
    int i, j, k, deg;
    for (i = 0; i <= n; ++i) out[i] = 0.0;
    for (j = 0; j <= n; ++j) {
        p[0] = 1.0;
        deg = 0;
        for (k = 0; k < n; ++k) {
            double sgn = k < j ? -1.0 : 1.0;
            p[deg + 1] = 0.0;
            for (i = deg + 1; i > 0; --i) p[i] += sgn * p[i - 1];
            ++deg;
        }
        for (i = 0; i <= n; ++i) out[i] += cs[n - j] * wj * p[i];
        wj *= 2.0 / @_T;
    }
}

void @_default_params(@_params *prm)
{
@DEFAULTS
}

int @_set_params(@_state *s, const @_params *prm)
{
    double cn[@P_NC], cd[@P_NC], bz[@P_NC], az[@P_NC], d[@P_NB];
    double *a = s->work, *inv = s->work + @P_NS * @P_NS;
    int b, i, j, k, n = @P_NS;
@COEFFS
    for (b = 0; b < @P_NB; ++b) {
        int c = @_coef[b], q = @_ord[b];
        @_tustin(q, cn + c, bz + c);
        @_tustin(q, cd + c, az + c);
        if (!(az[c] != 0.0)) return -1;
        d[b] = bz[c] / az[c];
        for (i = 0; i <= q; ++i)
            if (!(bz[c + i] - bz[c + i] == 0.0 && az[c + i] - az[c + i] == 0.0)) return -1;
    }
    /* (I - F)^-1 by Gauss-Jordan with partial pivoting; F: the undelayed feedthrough */
    for (i = 0; i < n * n; ++i) a[i] = 0.0;
    for (i = 0; i < n; ++i) a[i * n + i] = 1.0;
    for (b = 0; b < @P_NB; ++b)
        if (@_len[b] == 0) a[@_dst[b] * n + @_src[b]] -= d[b];
    {
        for (i = 0; i < n * n; ++i) inv[i] = 0.0;
        for (i = 0; i < n; ++i) inv[i * n + i] = 1.0;
        for (k = 0; k < n; ++k) {
            int piv = k;
            double t;
            for (i = k + 1; i < n; ++i)
                if ((a[i * n + k] < 0 ? -a[i * n + k] : a[i * n + k]) >
                    (a[piv * n + k] < 0 ? -a[piv * n + k] : a[piv * n + k])) piv = i;
            if (!(a[piv * n + k] != 0.0)) return -1;
            for (j = 0; j < n; ++j) {
                t = a[k * n + j]; a[k * n + j] = a[piv * n + j]; a[piv * n + j] = t;
                t = inv[k * n + j]; inv[k * n + j] = inv[piv * n + j]; inv[piv * n + j] = t;
            }
            t = a[k * n + k];
            for (j = 0; j < n; ++j) { a[k * n + j] /= t; inv[k * n + j] /= t; }
            for (i = 0; i < n; ++i) {
                if (i == k) continue;
                t = a[i * n + k];
                if (t == 0.0) continue;
                for (j = 0; j < n; ++j) {
                    a[i * n + j] -= t * a[k * n + j];
                    inv[i * n + j] -= t * inv[k * n + j];
                }
            }
        }
        for (i = 0; i < n * n; ++i) {
            if (!(inv[i] - inv[i] == 0.0)) return -1;
        }
        /* valid: commit everything at once (the states are kept: bumpless) */
        for (i = 0; i < n * n; ++i) s->g[i] = (@_real)inv[i];
    }
    for (i = 0; i < @P_NC; ++i) { s->bz[i] = bz[i]; s->az[i] = az[i]; }
    for (b = 0; b < @P_NB; ++b) s->d[b] = (@_real)d[b];
    s->prm = *prm;
    return 0;
}

void @_reset(@_state *s)
{
    int i;
    for (i = 0; i < @P_NW; ++i) s->w[i] = 0;
    for (i = 0; i < @P_NBUF; ++i) s->buf[i] = 0;
    for (i = 0; i < @P_NB; ++i) s->head[i] = 0;
    s->age = 0;
}

void @_init(@_state *s)
{
    @_params prm;
    int i;
    for (i = 0; i < @P_NC; ++i) { s->bz[i] = 0.0; s->az[i] = 1.0; }
    for (i = 0; i < @P_NS * @P_NS; ++i) s->g[i] = 0;
    @_default_params(&prm);
    (void)@_set_params(s, &prm);
    @_reset(s);
}

void @_step(@_state *s, const @_inputs *in, int fresh, @_outputs *out)
{
    @_real v[@P_NI], y[@P_NO];
    int b, i, j, n = @P_NS, expired;
@INPUTS
    for (i = 0; i < n; ++i) s->r[i] = 0;
    for (i = 0; i < @P_NI; ++i) s->r[@_in_sig[i]] += v[i];
    for (b = 0; b < @P_NB; ++b) {       /* each block: its part free of this tick's input */
        int c = @_coef[b], h = @_hist[b], q = @_ord[b];
        double fr = 0.0;
        for (i = 1; i <= q; ++i)
            fr += (s->bz[c + i] - (double)s->d[b] * s->az[c + i]) * (double)s->w[h + i - 1];
        s->f[b] = (@_real)fr;
        if (@_len[b] > 0) {
            s->u[b] = s->buf[@_buf[b] + s->head[b]];
            s->r[@_dst[b]] += s->d[b] * s->u[b] + s->f[b];
        } else {
            s->r[@_dst[b]] += s->f[b];
        }
    }
    for (i = 0; i < n; ++i) {            /* the signals */
        @_real acc = 0;
        for (j = 0; j < n; ++j) acc += s->g[i * n + j] * s->r[j];
        s->s[i] = acc;
    }
    for (i = 0; i < @P_NO; ++i) y[i] = @_out_sig[i] >= 0 ? s->s[@_out_sig[i]] : 0;
    for (b = 0; b < @P_NB; ++b) {       /* outputs, then the states and buffers */
        int c = @_coef[b], h = @_hist[b], q = @_ord[b];
        double wn;
        if (@_len[b] == 0) s->u[b] = s->s[@_src[b]];
        if (@_msg[b] >= 0) y[@_msg[b]] += s->d[b] * s->u[b] + s->f[b];
        if (q > 0) {
            wn = (double)s->u[b];
            for (i = 1; i <= q; ++i) wn -= s->az[c + i] * (double)s->w[h + i - 1];
            wn /= s->az[c];
            for (i = q - 1; i > 0; --i) s->w[h + i] = s->w[h + i - 1];
            s->w[h] = (@_real)wn;
        }
        if (@_len[b] > 0) {
            s->buf[@_buf[b] + s->head[b]] = s->s[@_src[b]];
            s->head[b] = (s->head[b] + 1) % @_len[b];
        }
    }
    s->age = fresh ? 0 : s->age + 1;
    expired = s->prm.watchdog_ticks > 0 && s->age > s->prm.watchdog_ticks;
    out->watchdog = expired;
@OUTPUTS
}
"""


def source(prog: Program, banner: str) -> str:
    """``<process>.c``."""
    p, P = prog.ident, prog.ident.upper()
    defaults = [f"    prm->{n} = {_lit(v)};" for n, v in prog.parameters.items()]
    defaults += [f"    prm->{lim[0]} = {_lit(lim[1])};" for lim in prog.limits if lim]
    defaults.append(f"    prm->watchdog_ticks = {prog.watchdog_ticks};")
    inputs = [f"    v[{i}] = in->{c_ident(n)};" for i, n in enumerate(prog.inputs)]
    if not prog.inputs:
        inputs = ["    v[0] = 0;", "    (void)in;"]
    outputs = []
    for i, (name, lim) in enumerate(zip(prog.outputs, prog.limits)):
        if lim:
            m = f"(@_real)s->prm.{lim[0]}"
            outputs.append(f"    if (y[{i}] > {m}) y[{i}] = {m};")
            outputs.append(f"    if (y[{i}] < -{m}) y[{i}] = -{m};")
        outputs.append(f"    out->{c_ident(name)} = expired ? 0 : y[{i}];")
    body = (_BODY.replace("@DEFAULTS", "\n".join(defaults))
            .replace("@COEFFS", "\n".join(_coeffs(prog)) or "    (void)prm;")
            .replace("@INPUTS", "\n".join(inputs)).replace("@OUTPUTS", "\n".join(outputs)))
    return (banner + "#include <math.h>\n" + f'#include "{p}.h"\n\n' + _tables(prog)
            + body.replace("@P_", f"{P}_").replace("@_", f"{p}_"))


def harness(prog: Program) -> str:
    """``<process>_main.c``: CSV inputs on stdin (a header line, then one call per line,
    every command fresh), CSV outputs (``%.17g``) on stdout."""
    p = prog.ident
    parse = []
    for n in prog.inputs:
        parse += [f"        in.{c_ident(n)} = ({p}_real)strtod(c, &end);",
                  "        if (end == c) { fprintf(stderr, \"bad number on line %ld\\n\", "
                  "line_no); return 2; }",
                  "        c = end; if (*c == ',') ++c;"]
    fmt = ",".join(["%.17g"] * len(prog.outputs))
    args = ", ".join(f"(double)out.{c_ident(n)}" for n in prog.outputs)
    return (f"/* CSV harness of {p}.c, generated by seactl export. */\n"
            "#include <stdio.h>\n#include <stdlib.h>\n" f'#include "{p}.h"\n\n'
            "int main(void)\n{\n    char line[4096];\n    long line_no = 1;\n"
            f"    static {p}_state s; /* static: long delay buffers stay off the stack */\n"
            f"    {p}_inputs in;\n    {p}_outputs out;\n"
            f"    {p}_init(&s);\n"
            "    if (!fgets(line, sizeof line, stdin)) return 1; /* header */\n"
            f'    printf("{",".join(prog.outputs)}\\n");\n'
            "    while (fgets(line, sizeof line, stdin)) {\n"
            "        char *c = line, *end;\n        ++line_no;\n        (void)end;\n"
            + "\n".join(parse) + ("\n" if parse else "")
            + f"        {p}_step(&s, &in, 1, &out);\n"
            f'        printf("{fmt}\\n", {args});\n'
            "    }\n    return 0;\n}\n")
