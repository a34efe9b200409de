"""Batched rollouts in C: the model's control cycle, CasADi's instructions emitted as C over lanes.

:meth:`Model.step <hybridnav.models.Model.step>` and :meth:`Model.rollout
<hybridnav.models.Model.rollout>` run here when a C compiler works. The code is the algorithm of
the SX function CasADi's path compiles (:meth:`Model._step_single`, parameters folded in),
operation for operation, written for several robots at once; it is compiled once per machine into
the native cache (:mod:`hybridnav.native`, keyed by the code) as a CPython extension (a plain
library called through ctypes where ``Python.h`` is missing) and takes any batch size and horizon.
Nearly all the time goes into the closed loop's transcendental functions (``atan2``, ``sin``,
``cos``, ``tan``, ...; glibc's cost 10-20 ns a call).

Variants (``HYBRIDNAV_SIMD`` chooses; the default is ``exact``):

``"exact"`` (default) and ``"scalar"``
    glibc's scalar functions, the arithmetic of CasADi's generated C: results bit for bit those of
    CasADi's compiled ``map`` (the tests compare them). ``exact`` works on two robots at once
    (their arithmetic in one SSE2 instruction, their function calls interleaved: 10-30 % faster
    than one at a time) and runs a last odd robot with the ``scalar`` code, so no robot slot is
    padding; ``scalar`` takes one robot at a time.
``"sse2"``, ``"avx2"``, ``"avx512"``; ``"auto"`` (the widest the CPU runs) — opt-in, approximate
    2, 4 or 8 robots per instruction with glibc's vector math library ``libmvec`` (x86-64, glibc
    >= 2.35), 3-5 times faster than ``exact``. Arithmetic, ``sqrt``, ``fabs``, ``fmax``/``fmin``,
    comparisons and selections are exactly the scalar code's, but libmvec's functions are not
    glibc's scalar ones: they differ by up to 4 ulp. Over 100 steps of trajectories that converge, states
    differ by ~1e-14; where the closed loop is sensitive (the unicycle's bearing at arrival, the
    heading controller circling its target, the tractor-trailer's orbits and jackknifed states)
    rounding differences grow without bound, up to O(1). Every robot goes through the same code
    in every batch (the last block's empty lanes repeat its last robot), so a robot's trajectory
    depends neither on its batch nor on its place in it, and ``step`` repeated is ``rollout``
    bit for bit; results may differ between machines (libmvec's variant per CPU). Models that
    call none of libmvec's functions (point mass, LbCS) get the widest variant by default: their
    results are exact.

Large batches are split over threads (:mod:`hybridnav.models.parallel`: :func:`threads`,
``HYBRIDNAV_THREADS``; ranges of robots the threads claim one at a time): each robot is
integrated alone, so the results do not depend on the number of threads.

Without a compiler, with ``HYBRIDNAV_NATIVE=0`` or ``HYBRIDNAV_JIT=0``, or for an operation this
module does not emit, :func:`get` returns ``None`` and the model uses CasADi's ``map``
(JIT-compiled or its virtual machine).
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
import platform
import sys
import threading
from ctypes import c_int, c_int64, c_void_p

import casadi as cs
import numpy as np

from hybridnav import native
from hybridnav.models.parallel import THREAD_MIN_NS, THREADS_ENV, run, threads
from hybridnav.native import pycall

log = logging.getLogger(__name__)

__all__ = ["ENV", "THREADS_ENV", "THREAD_MIN_NS", "Kernel", "allowed", "get", "run", "threads",
           "variant_names", "wanted"]

#: ``HYBRIDNAV_SIMD``: ``exact`` (default; also ``off``, ``0``), ``scalar``, or the opt-in
#: approximate ``auto``, ``sse2``, ``avx2``, ``avx512``
ENV = "HYBRIDNAV_SIMD"

# name -> (bit, lanes, libmvec ISA letter (None: glibc's scalar functions), GCC target)
_VARIANTS = {
    "scalar": (1, 1, None, None),
    "exact": (2, 2, None, None),
    "sse2": (4, 2, "b", "sse2"),
    "avx2": (8, 4, "d", "avx2,fma"),
    "avx512": (16, 8, "e", "avx512f"),
}
_CPU = {"sse2": '__builtin_cpu_supports("sse2")',
        "avx2": '__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")',
        "avx512": '__builtin_cpu_supports("avx512f")'}
_SQRT = {"sse2": "_mm_sqrt_pd", "avx2": "_mm256_sqrt_pd", "avx512": "_mm512_sqrt_pd"}

# op -> (arity, C of the scalar code, with {0} {1} the operands). The scalar forms are CasADi's
# code generator's (casadi_sq is x*x, casadi_fmax/fmin are C99 fmax/fmin).
_SCALAR = {
    cs.OP_ADD: (2, "({0}+{1})"), cs.OP_SUB: (2, "({0}-{1})"), cs.OP_MUL: (2, "({0}*{1})"),
    cs.OP_DIV: (2, "({0}/{1})"), cs.OP_NEG: (1, "(-{0})"), cs.OP_SQ: (1, "({0}*{0})"),
    cs.OP_TWICE: (1, "(2.*{0})"), cs.OP_INV: (1, "(1./{0})"), cs.OP_SQRT: (1, "sqrt({0})"),
    cs.OP_FABS: (1, "fabs({0})"), cs.OP_SIGN: (1, "hn_sign({0})"),
    cs.OP_FMAX: (2, "fmax({0},{1})"), cs.OP_FMIN: (2, "fmin({0},{1})"),
    cs.OP_LT: (2, "({0}<{1})"), cs.OP_LE: (2, "({0}<={1})"), cs.OP_EQ: (2, "({0}=={1})"),
    cs.OP_NE: (2, "({0}!={1})"), cs.OP_NOT: (1, "(!{0})"), cs.OP_AND: (2, "({0}&&{1})"),
    cs.OP_OR: (2, "({0}||{1})"), cs.OP_IF_ELSE_ZERO: (2, "({0}?{1}:0)"),
    cs.OP_ASSIGN: (1, "{0}"),
}
# functions of libm: op -> (arity, name); those libmvec has are vectorized, the others run lane by
# lane with the scalar function (exactly the scalar code's)
_LIBM = {
    cs.OP_SIN: (1, "sin"), cs.OP_COS: (1, "cos"), cs.OP_TAN: (1, "tan"), cs.OP_ASIN: (1, "asin"),
    cs.OP_ACOS: (1, "acos"), cs.OP_ATAN: (1, "atan"), cs.OP_ATAN2: (2, "atan2"),
    cs.OP_EXP: (1, "exp"), cs.OP_LOG: (1, "log"), cs.OP_POW: (2, "pow"),
    cs.OP_CONSTPOW: (2, "pow"), cs.OP_SINH: (1, "sinh"), cs.OP_COSH: (1, "cosh"),
    cs.OP_TANH: (1, "tanh"), cs.OP_ASINH: (1, "asinh"), cs.OP_ACOSH: (1, "acosh"),
    cs.OP_ATANH: (1, "atanh"), cs.OP_ERF: (1, "erf"), cs.OP_LOG1P: (1, "log1p"),
    cs.OP_EXPM1: (1, "expm1"), cs.OP_HYPOT: (2, "hypot"), cs.OP_FLOOR: (1, "floor"),
    cs.OP_CEIL: (1, "ceil"), cs.OP_FMOD: (2, "fmod"), cs.OP_COPYSIGN: (2, "copysign"),
}
_MVEC = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "exp", "log", "pow", "sinh",
         "cosh", "tanh", "asinh", "acosh", "atanh", "erf", "log1p", "expm1", "hypot"}
# vector forms of the non-libm operations (V: the lane type; M: the mask type; BC: a constant in
# every lane; SEL(m, a, b): a where m, else b; ONE: 1.0 where m, else 0.0)
_VEC = {
    cs.OP_ADD: "({0}+{1})", cs.OP_SUB: "({0}-{1})", cs.OP_MUL: "({0}*{1})",
    cs.OP_DIV: "({0}/{1})", cs.OP_NEG: "(-{0})", cs.OP_SQ: "({0}*{0})",
    cs.OP_TWICE: "(BC(2.)*{0})", cs.OP_INV: "(BC(1.)/{0})", cs.OP_SQRT: "VSQRT({0})",
    cs.OP_FABS: "((V)((M){0} & BCM(0x7fffffffffffffffLL)))",
    cs.OP_SIGN: "SEL({0}<BC(0.), BC(-1.), SEL({0}>BC(0.), BC(1.), {0}))",
    # C99 fmax/fmin: the other operand where one is NaN; glibc's x86-64 code returns the second
    # operand when they compare equal (maxsd/minsd)
    cs.OP_FMAX: "SEL(({0}>{1}) | ({1}!={1}), {0}, {1})",
    cs.OP_FMIN: "SEL(({0}<{1}) | ({1}!={1}), {0}, {1})",
    cs.OP_LT: "ONE({0}<{1})", cs.OP_LE: "ONE({0}<={1})", cs.OP_EQ: "ONE({0}=={1})",
    cs.OP_NE: "ONE({0}!={1})", cs.OP_NOT: "ONE({0}==BC(0.))",
    cs.OP_AND: "ONE(({0}!=BC(0.)) & ({1}!=BC(0.)))",
    cs.OP_OR: "ONE(({0}!=BC(0.)) | ({1}!=BC(0.)))",
    cs.OP_IF_ELSE_ZERO: "SEL({0}!=BC(0.), {1}, BC(0.))",
    cs.OP_ASSIGN: "{0}",
}


def _literal(c: float) -> str:
    if math.isnan(c):
        return "NAN"
    if math.isinf(c):
        return "HUGE_VAL" if c > 0 else "(-HUGE_VAL)"
    return float(c).hex()


class _Unsupported(Exception):
    pass


def _body(fn: cs.Function, nx: int, nt: int) -> tuple[str, str, set[str]]:
    """The cycle's statements in two dialects (scalar, vector) and the libm functions it calls.

    Reads ``s[0..nx)`` (state) and ``t[0..nt)`` (target), writes ``o[0..nx)``; work variables
    ``w<i>`` follow CasADi's work vector, so the operations and their order are CasADi's.
    """
    scalar, vector, funcs = [], [], set()
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        ins, outs = fn.instruction_input(k), fn.instruction_output(k)
        if op == cs.OP_INPUT:
            src = ("s", "t")[ins[0]]
            scalar.append(f"w{outs[0]}={src}[{ins[1]}];")
            vector.append(f"w{outs[0]}={src}[{ins[1]}];")
            continue
        if op == cs.OP_OUTPUT:
            if outs[0] != 0:
                raise _Unsupported("more than one output")
            scalar.append(f"o[{outs[1]}]=w{ins[0]};")
            vector.append(f"o[{outs[1]}]=w{ins[0]};")
            continue
        if op == cs.OP_CONST:
            lit = _literal(fn.instruction_constant(k))
            scalar.append(f"w{outs[0]}={lit};")
            vector.append(f"w{outs[0]}=BC({lit});")
            continue
        args = [f"w{i}" for i in ins]
        if op in _SCALAR:
            arity, form = _SCALAR[op]
            scalar.append(f"w{outs[0]}={form.format(*args[:arity])};")
            vector.append(f"w{outs[0]}={_VEC[op].format(*args[:arity])};")
        elif op in _LIBM:
            arity, name = _LIBM[op]
            funcs.add(name)
            scalar.append(f"w{outs[0]}={name}({','.join(args[:arity])});")
            vector.append(f"w{outs[0]}=V_{name}({','.join(args[:arity])});")
        else:
            raise _Unsupported(f"CasADi operation {op}")
    decl = ", ".join(f"w{i}" for i in range(max(fn.sz_w(), 1)))
    return (f"double {decl};\n" + "\n".join(scalar),
            f"V {decl};\n" + "\n".join(vector), funcs)



_LOOP = r"""
/* robots [0, n) in blocks of W lanes; {PAD} */
static void run_{ID}(int64_t n, int64_t steps, const double *X, const double *T, double *out,
                     int64_t rs, int64_t ks)
{{
  int64_t blocks = 0;
  for (int64_t i0 = 0; i0 < n; i0 += W, blocks++) {{
    int64_t cnt = n - i0 < W ? n - i0 : W;
    V s[NX], t[NT], o[NX];
    double sb[NX * W], tb[NT * W];       /* lane l of vector j is double j * W + l */
    for (int l = 0; l < W; l++) {{
      int64_t i = i0 + (l < cnt ? l : cnt - 1);
      for (int j = 0; j < NX; j++) sb[j * W + l] = X[i * NX + j];
      for (int j = 0; j < NT; j++) tb[j * W + l] = T[i * NT + j];
    }}
    memcpy(s, sb, sizeof s);
    memcpy(t, tb, sizeof t);
    for (int64_t k = 0; k < steps; k++) {{
      {{
{BODY}
      }}
      for (int l = 0; l < cnt; l++) {{
        double *p = out + (i0 + l) * rs + k * ks;
        for (int j = 0; j < NX; j++) p[j] = LANE(o[j], l);
      }}
      for (int j = 0; j < NX; j++) s[j] = o[j];
    }}
  }}
  hn_count(blocks * W * steps);
}}
"""

_HEAD = r"""/* generated by hybridnav.models.kernel: {NAME} */
#ifdef HN_PYTHON
#define PY_SSIZE_T_CLEAN
#include <Python.h>           /* first, as Python asks */
#endif
#include <math.h>
#include <stdint.h>
#include <string.h>
#define NX {NX}
#define NT {NT}
static inline double hn_sign(double x) {{ return x < 0 ? -1 : x > 0 ? 1 : x; }}
/* robot slots computed (robots x steps, with a SIMD variant's empty lanes): the tests read it */
static int64_t hn_slots_total;
static void hn_count(int64_t k) {{ __atomic_fetch_add(&hn_slots_total, k, __ATOMIC_RELAXED); }}
int64_t hn_slots(void) {{ return __atomic_load_n(&hn_slots_total, __ATOMIC_RELAXED); }}
"""

# the lane macros of a vector variant (V: the lane type; M: its mask type; BC: a constant in every
# lane; SEL(m, a, b): a where m, else b; ONE: 1.0 where m, else 0.0)
_LANES_HEAD = r"""
typedef double hn_v_{NAME} __attribute__((vector_size({BYTES})));
typedef long long hn_m_{NAME} __attribute__((vector_size({BYTES})));
#define V hn_v_{NAME}
#define M hn_m_{NAME}
#define W {LANES}
#define LANE(v, l) (v)[l]
#define BC(c) ((V){{{BCS}}})
#define BCM(c) ((M){{{BCS}}})
#define SEL(m, a, b) ((V)((((M)(a)) & ((M)(m))) | (((M)(b)) & ~((M)(m)))))
#define ONE(m) ((V)(((M)BC(1.)) & ((M)(m))))
"""

_LANES_TAIL = r"""
#undef V
#undef M
#undef W
#undef LANE
#undef BC
#undef BCM
#undef SEL
#undef ONE
#undef VSQRT
"""

# an exact variant: whole blocks of lanes, then the rest one robot at a time (same results)
_TAIL = r"""
static void run_{ID}(int64_t n, int64_t steps, const double *X, const double *T, double *out,
                     int64_t rs, int64_t ks)
{{
  int64_t m = n - n % {W};
  run_{ID}_blocks(m, steps, X, T, out, rs, ks);
  if (m < n) run_scalar(n - m, steps, X + m * NX, T + m * NT, out + m * rs, rs, ks);
}}
"""

_DISPATCH = r"""
int hn_variants(void)
{{
  int v = 3;
{CHECKS}
  return v;
}}

int hn_run(int id, int64_t n, int64_t steps, const double *X, const double *T, double *out,
           int64_t rs, int64_t ks)
{{
  switch (id) {{
{CASES}
  default: return -1;
  }}
  return 0;
}}
"""

# the entry point Python calls (a CPython extension: ~0.3 us a call against ~5 us through ctypes,
# which pays for three ndarray.ctypes objects); ctypes calls hn_run where Python.h is missing
_PYTHON = r"""
#ifdef HN_PYTHON

static int hn_buffer(PyObject *o, Py_buffer *b, int writable)
{
  if (PyObject_GetBuffer(o, b, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT
                         | (writable ? PyBUF_WRITABLE : 0)) < 0)
    return -1;
  if (b->itemsize != 8 || b->format == NULL || strcmp(b->format, "d") != 0) {
    PyBuffer_Release(b);
    PyErr_SetString(PyExc_TypeError, "expected C-contiguous float64 arrays");
    return -1;
  }
  return 0;
}

/* run(variant, steps, rs, ks, offset, X, T, out) */
static PyObject *hn_py_run(PyObject *self, PyObject *const *a, Py_ssize_t na)
{
  long long v[5];
  Py_buffer bx, bt, bo;
  int rc;
  if (na != 8) {
    PyErr_SetString(PyExc_TypeError, "run() takes 8 arguments");
    return NULL;
  }
  for (int i = 0; i < 5; i++) {
    v[i] = PyLong_AsLongLong(a[i]);
    if (v[i] == -1 && PyErr_Occurred()) return NULL;
  }
  if (hn_buffer(a[5], &bx, 0) < 0) return NULL;
  if (hn_buffer(a[6], &bt, 0) < 0) { PyBuffer_Release(&bx); return NULL; }
  if (hn_buffer(a[7], &bo, 1) < 0) { PyBuffer_Release(&bx); PyBuffer_Release(&bt); return NULL; }
  int64_t n = bx.len / (8 * NX), steps = v[1], rs = v[2], ks = v[3], off = v[4];
  int64_t room = bo.len / 8;
  if (bx.len != n * NX * 8 || bt.len != n * NT * 8 || steps < 0 || off < 0 || rs < 0 || ks < 0
      || (n > 0 && steps > 0 && off + (n - 1) * rs + (steps - 1) * ks + NX > room)) {
    rc = -2;
  } else {
    Py_BEGIN_ALLOW_THREADS
    rc = hn_run((int)v[0], n, steps, (const double *)bx.buf, (const double *)bt.buf,
                (double *)bo.buf + off, rs, ks);
    Py_END_ALLOW_THREADS
  }
  PyBuffer_Release(&bx);
  PyBuffer_Release(&bt);
  PyBuffer_Release(&bo);
  if (rc == -2) {
    PyErr_SetString(PyExc_ValueError, "run(): array sizes do not match");
    return NULL;
  }
  if (rc != 0) {
    PyErr_SetString(PyExc_ValueError, "run(): variant not available");
    return NULL;
  }
  Py_RETURN_NONE;
}

static PyObject *hn_py_variants(PyObject *self, PyObject *unused)
{
  return PyLong_FromLong(hn_variants());
}

static PyObject *hn_py_slots(PyObject *self, PyObject *unused)
{
  return PyLong_FromLongLong(hn_slots());
}

static PyMethodDef hn_methods[] = {
  {"run", (PyCFunction)(void (*)(void))hn_py_run, METH_FASTCALL, "run the kernel"},
  {"slots", hn_py_slots, METH_NOARGS, "robot slots computed so far (robots x steps)"},
  {"variants", hn_py_variants, METH_NOARGS, "bit set of the variants this CPU runs"},
  {NULL, NULL, 0, NULL}
};

static struct PyModuleDef hn_module = {PyModuleDef_HEAD_INIT, .m_name = "_hn_rollout",
                                        .m_size = -1, .m_methods = hn_methods};

PyMODINIT_FUNC PyInit__hn_rollout(void) { return PyModule_Create(&hn_module); }
#endif
"""



def _vector_supported() -> bool:
    """x86-64 Linux with glibc (libmvec and its x86-64 ABI): where the SIMD variants are built."""
    return (platform.machine().lower() in ("x86_64", "amd64") and sys.platform.startswith("linux")
            and platform.libc_ver()[0] == "glibc")


def _lanewise(f: str, arity: int, name: str) -> str:
    """``V_f``: the scalar function ``f`` lane by lane (exactly the scalar code's results)."""
    a = ", ".join(f"V a{i}" for i in range(arity))
    call = ", ".join(f"a{i}[l]" for i in range(arity))
    return (f"static inline V hn_{f}_{name}({a}) {{ V r; for (int l = 0; l < W; l++) "
            f"r[l] = {f}({call}); return r; }}\n#define V_{f} hn_{f}_{name}\n")


def source(fn: cs.Function, nx: int, nt: int, name: str, simd: bool = False) -> str:
    """The C source of the kernel for the single-robot control cycle ``fn`` (SX, ``x, target ->
    x_next``): the ``scalar`` and ``exact`` variants and, with ``simd``, the SSE2, AVX2 and
    AVX-512 ones (exact too where the cycle calls no function libmvec has)."""
    scalar_body, vector_body, funcs = _body(fn, nx, nt)
    exact = not funcs & _MVEC
    parts = [_HEAD.format(NAME=name, NX=nx, NT=nt)]
    # scalar: one robot at a time
    parts.append("#define V double\n#define W 1\n#define LANE(v, l) (v)\n")
    parts.append(_LOOP.format(ID="scalar", BODY=scalar_body, PAD="no padding"))
    parts.append("#undef V\n#undef W\n#undef LANE\n")
    # exact: two robots, glibc's scalar functions lane by lane; an odd last robot runs scalar
    parts.append(_LANES_HEAD.format(NAME="exact", BYTES=16, LANES=2, BCS="c,c"))
    parts.append("static inline V hn_sqrt_exact(V a) { V r; r[0] = sqrt(a[0]); "
                 "r[1] = sqrt(a[1]); return r; }\n#define VSQRT(a) hn_sqrt_exact(a)\n")
    parts.extend(_lanewise(f, _LIBM_ARITY[f], "exact") for f in sorted(funcs))
    parts.append(_LOOP.format(ID="exact_blocks", BODY=vector_body, PAD="whole blocks only"))
    parts.append(_LANES_TAIL + "".join(f"#undef V_{f}\n" for f in sorted(funcs)))
    parts.append(_TAIL.format(ID="exact", W=2))
    checks = []
    cases = ["  case 1: run_scalar(n, steps, X, T, out, rs, ks); break;",
             "  case 2: run_exact(n, steps, X, T, out, rs, ks); break;"]
    if simd:
        parts.append("#include <immintrin.h>\n")
        for vname in ("sse2", "avx2", "avx512"):
            bit, lanes, isa, target = _VARIANTS[vname]
            parts.append(f'#pragma GCC push_options\n#pragma GCC target("{target}")\n')
            parts.append(_LANES_HEAD.format(NAME=vname, BYTES=8 * lanes, LANES=lanes,
                                            BCS=",".join(["c"] * lanes)))
            parts.append(f"#define VSQRT(a) ((V){_SQRT[vname]}(a))\n")
            for f in sorted(funcs):
                arity = _LIBM_ARITY[f]
                if f in _MVEC:
                    mangled = f"_ZGV{isa}N{lanes}{'v' * arity}_{f}"
                    parts.append(f"extern V {mangled}({', '.join(['V'] * arity)});\n"
                                 f"#define V_{f} {mangled}\n")
                else:
                    parts.append(_lanewise(f, arity, vname))
            if exact:        # no libmvec function: results are the scalar code's
                parts.append(_LOOP.format(ID=f"{vname}_blocks", BODY=vector_body,
                                          PAD="whole blocks only"))
            else:
                parts.append(_LOOP.format(ID=vname, BODY=vector_body, PAD="the last block's "
                                          "empty lanes repeat its last robot"))
            parts.append(_LANES_TAIL + "".join(f"#undef V_{f}\n" for f in sorted(funcs)))
            parts.append("#pragma GCC pop_options\n")
            if exact:
                parts.append(_TAIL.format(ID=vname, W=lanes))
            checks.append(f"  if ({_CPU[vname]}) v |= {bit};")
            cases.append(f"  case {bit}: run_{vname}(n, steps, X, T, out, rs, ks); break;")
        checks.insert(0, "  __builtin_cpu_init();")
    parts.append(_DISPATCH.format(CHECKS="\n".join(checks), CASES="\n".join(cases)))
    parts.append(_PYTHON)
    return "".join(parts)


_LIBM_ARITY = {name: arity for arity, name in _LIBM.values()}


class Kernel:
    """A compiled model cycle over a batch (see :meth:`run`).

    Attributes
    ----------
    variant : str
        ``"exact"``, ``"scalar"``, ``"sse2"``, ``"avx2"`` or ``"avx512"``.
    lanes : int
        Robots per block (1, 2, 4, 8).
    cost_ns : float
        Rough nanoseconds per robot-step, from the cycle's operations (for splitting batches over
        threads only where a thread gets enough work).
    path : pathlib.Path
        The compiled library (a CPython extension, or a plain library called through ctypes).
    exact : bool
        Results bit for bit CasADi's compiled path (glibc's scalar functions, or none at all).
    """

    def __init__(self, call, variant: str, path, exact: bool, slots, cost_ns: float) -> None:
        self._call = call
        self._slots = slots
        self.variant = variant
        self.bit, self.lanes = _VARIANTS[variant][:2]
        self.path = path
        self.exact = exact
        self.cost_ns = cost_ns

    def run(self, X: np.ndarray, T: np.ndarray, out: np.ndarray, steps: int, rs: int, ks: int,
            offset: int = 0) -> None:
        """Advance the robots of ``X`` (C-contiguous float64 ``(n, nx)``) towards ``T`` (``(n,
        nt)``) for ``steps`` cycles; robot ``i``'s state after cycle ``k + 1`` goes to the
        doubles ``out.flat[offset + i * rs + k * ks :][:nx]`` (``out`` C-contiguous float64)."""
        self._call(self.bit, steps, rs, ks, offset, X, T, out)

    def slots(self) -> int:
        """Robot slots its library has computed in this process so far (robots x steps, a SIMD
        variant's empty lanes included; the library is shared by the models of equal code)."""
        return int(self._slots())


def _ctypes_call(lib: ctypes.CDLL):
    f = lib.hn_run
    f.argtypes = [c_int, c_int64, c_int64, c_void_p, c_void_p, c_void_p, c_int64, c_int64]
    f.restype = c_int

    def call(variant, steps, rs, ks, offset, X, T, out):
        n = len(X)
        if (X.size != n * X.shape[-1] or not (X.flags.c_contiguous and T.flags.c_contiguous
                                              and out.flags.c_contiguous)
                or (n and steps and offset + (n - 1) * rs + (steps - 1) * ks + X.shape[-1]
                    > out.size)):
            raise ValueError("run(): array sizes do not match")
        if f(variant, n, steps, X.ctypes.data, T.ctypes.data, out.ctypes.data + 8 * offset,
             rs, ks) != 0:
            raise ValueError("run(): variant not available")

    lib.hn_variants.argtypes = []
    lib.hn_variants.restype = c_int
    lib.hn_slots.argtypes = []
    lib.hn_slots.restype = c_int64
    return call, lib.hn_variants, lib.hn_slots


_KERNELS: dict[tuple, Kernel | None] = {}
_LOCK = threading.Lock()


def _cost_ns(fn: cs.Function, variant: str) -> float:
    """Rough ns per robot-step: ~8 ns a glibc scalar function call, ~12 ns per vector of a
    libmvec one, ~0.5 ns per other operation and vector (measured orders of magnitude)."""
    lanes, isa = _VARIANTS[variant][1], _VARIANTS[variant][2]
    cost = 0.0
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        if op in _LIBM:
            cost += 12.0 / lanes if isa and _LIBM[op][1] in _MVEC else 8.0
        elif op not in (cs.OP_INPUT, cs.OP_OUTPUT, cs.OP_CONST):
            cost += 0.5 / lanes
    return max(cost, 0.5)


def variant_names() -> tuple[str, ...]:
    """The variants: the exact ones, then the opt-in SIMD ones, narrowest first."""
    return tuple(_VARIANTS)


def wanted() -> str:
    """The variant ``HYBRIDNAV_SIMD`` asks for: ``exact`` (default; also ``off``, ``0``, or an
    unknown value), ``scalar``, ``auto`` (the widest SIMD variant the CPU runs), ``sse2``,
    ``avx2`` or ``avx512``."""
    v = os.environ.get(ENV, "").strip().lower()
    return v if v in _VARIANTS or v == "auto" else "exact"


def allowed() -> bool:
    """Whether kernels may be compiled: not with ``HYBRIDNAV_NATIVE=0`` or ``HYBRIDNAV_JIT=0``."""
    from hybridnav.models.compile import jit_allowed

    return native.enabled() and jit_allowed()


def get(model, variant: str | None = None) -> Kernel | None:
    """The compiled kernel of ``model``'s control cycle (built once per process and machine),
    or ``None`` where there is none (no compiler, kernels or JIT switched off, an operation this
    module does not emit). ``variant`` overrides ``HYBRIDNAV_SIMD``."""
    if not allowed():
        return None
    want = variant or wanted()
    key = model._key() + (want,)
    with _LOCK:
        if key in _KERNELS:
            return _KERNELS[key]
    k = _make(model, want)
    with _LOCK:
        _KERNELS[key] = k
    return k


def _load_extension(name: str, code: str, options: tuple[str, ...]):
    """The kernel built as a CPython extension: ``(run, variants, slots, path)``, or None (no
    ``Python.h``, a failed build or load)."""
    path = pycall.extension_file(name, code, options)
    mod = None if path is None else pycall.load_extension(path, "_hn_rollout")
    if mod is None:
        return None
    return mod.run, mod.variants, mod.slots, path


def _load(name: str, code: str, options: tuple[str, ...]):
    """``(run, variants, slots, path)`` of the kernel: a CPython extension, else through
    ctypes."""
    got = _load_extension(name, code, options)
    if got is not None:
        return got
    lib = native.build(name, code, options)
    if lib is None:
        return None
    return (*_ctypes_call(lib), lib._name)


def _make(model, want: str) -> Kernel | None:
    try:
        fn = model._step_single()
        nx, nt = model.nx, model.target_size
        funcs = _body(fn, nx, nt)[2]
        name = f"rollout-{model.name}"
        simd_exact = not funcs & _MVEC           # the SIMD variants compute exactly
        got = None
        if _vector_supported() and (want not in ("exact", "scalar") or simd_exact):
            got = _load(name, source(fn, nx, nt, name, simd=True),
                        () if simd_exact else ("-lmvec",))
            if got is None:
                log.info("SIMD kernel for %s unavailable; the exact one", model.name)
        if got is None:
            got = _load(name, source(fn, nx, nt, name), ())
    except _Unsupported as exc:
        log.info("no compiled kernel for %s: %s", model.name, exc)
        return None
    if got is None:
        return None
    call, variants, slots, path = got
    have = variants()
    widest = next(v for v in ("avx512", "avx2", "sse2", "exact") if have & _VARIANTS[v][0])
    if want == "auto" or (want == "exact" and simd_exact):
        variant = widest
    elif want in _VARIANTS and have & _VARIANTS[want][0]:
        variant = want
    else:
        log.info("kernel variant %s not available here; the exact one", want)
        variant = "exact"
    return Kernel(call, variant, path, exact=simd_exact or variant in ("exact", "scalar"),
                  slots=slots, cost_ns=_cost_ns(fn, variant))
