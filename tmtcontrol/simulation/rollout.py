"""Compiled rollouts: a CasADi ``mapaccum`` of the per-period step, generated
as C, compiled with the system compiler and cached on disk.

``Rollout(step)`` turns ``step: ["s","u","p"] -> ["s_next","log"]`` into a
runner whose :meth:`Rollout.run` advances N periods with no Python per step:
the per-step Function (SX, or MX calling SX Functions) is rolled out with
``mapaccum`` over a fixed chunk of periods, that chunk is code-generated and
compiled once, and the chunks are called directly on NumPy buffers through
``ctypes`` (CasADi's own Python call path converts every input and output and
would cost more than the simulation itself).

Cache: ``$TMTCONTROL_CACHE`` if set, else ``$XDG_CACHE_HOME/tmtcontrol``
(``~/.cache/tmtcontrol``), keyed by the step's structure, the flags, the
CasADi version and the CPU, so a warm run generates no C. The structure is
the caller's key when it gives one (the Simulator's: the package's sources,
the structural settings and the law, so a warm run does not even build the
step; the library's own sparsity tables give the sizes), else the
Function's serialisation. Storage, verification, the per-user fallback of
an unwritable cache and pruning are in :mod:`tmtcontrol.cache`: a
library that does not match its recorded size and SHA-256 (a crash during a
write) is rebuilt, never loaded; a full disk leaves nothing partial and the
library is used uncached; with no compiler a valid cached library is still
used. The C is built in a private build folder under the cache
(:func:`tmtcontrol.cache.build_folder`) by :func:`tmtcontrol.processes.run_compiler`:
Ctrl-C or SIGTERM during the compile kills the compiler and its children at
once, removes the folder (the partial library and the compiler's
temporaries) and goes on as KeyboardInterrupt (the command line's one-line
exit 130/143); a SIGKILL of this process kills the compiler too. Without a compiler, or when ``compile=False`` (the caller's choice for
Functions that cannot be code-generated, such as CVODES), the same rollout
runs on CasADi's virtual machine — slower, identical in result.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import hashlib
import os
import pathlib
import platform
import re
import subprocess
import threading
import warnings

import casadi as ca
import numpy as np

from .. import cache
from ..cache import cache_dir, compiler
from ..processes import run_compiler

__all__ = ["cache_dir", "compiler", "Rollout"]

_FLAGS = ["-fno-trapping-math", "-ffp-contract=off", "-fno-math-errno", "-march=native",
          "-fno-semantic-interposition", "-fPIC", "-shared"]
"""-ffp-contract=off: no fused multiply-adds, so the compiled code computes
bit for bit what CasADi's virtual machine computes (tests), and a result does
not depend on whether its run was compiled. -fno-semantic-interposition: the
generated helpers (copy, sq, fmin, ...) are inlined instead of called through
the shared library's PLT (the rollout 6 % faster, the same arithmetic). The
optimisation level is :func:`optimisation_level`'s."""

O1_FROM = 20_000
"""Operations of a step's generated C (:func:`operations`) from which it is
compiled at -O1 rather than -O3. Measured by
``benchmarks/bench_compile_flags.py`` (table in docs/speed.md): the
simulated steps of the PUMA (4,655 operations with the contact refinement)
and the UR5 (18,606) and the UR5's tangent-linear step (14,718) keep -O3;
the Panda's simulated step (29,647: 8.0 s to compile at -O3, 3.3 s at
-O1, running 27 % slower) and its tangent step (27,372: 11.0 s against
4.75 s, 4 % slower) are compiled at -O1. No level changes a result: with
``-ffp-contract=off`` and no fast-math flag every level computes the same
IEEE arithmetic (the benchmark prints the difference: 0)."""

LEVEL: str | None = None
"""An optimisation level that overrides :func:`optimisation_level` (the
benchmark's; None in use)."""


def operations(fn: ca.Function) -> int:
    """The operations of ``fn``'s generated C: its elementary assignments
    (``aN=...``, one per SX instruction), each Function it calls counted
    once, however often called, and whatever kind calls it (an MX call, a
    ``map``, a ``Function.conditional``'s branches: the contact refinement's
    coarse plant step). Counted in the code CasADi generates, which is what
    the compiler sees (review 36: a count of the called Functions missed the
    switch's branches, whose API does not list them)."""
    with _SYMBOLIC:
        gen = ca.CodeGenerator("operations.c", {"with_header": False})
        gen.add(fn)
        return _assignments(gen.dump())


def _assignments(c_source: str) -> int:
    """The elementary assignments (``aN=...``) of CasADi-generated C."""
    return len(re.findall(r"^\s*a\d+=", c_source, re.M))


def optimisation_level(operations: int) -> str:
    """The compiler's -O level for a step of ``operations`` instructions
    (:func:`operations`): -O3, or -O1 from :data:`O1_FROM`."""
    if LEVEL is not None:
        return LEVEL
    return "-O3" if operations < O1_FROM else "-O1"


_CHUNK = 1000
COMPILE_AFTER = 10_000
"""With ``compile="auto"``, the steps run on the virtual machine before the
step is compiled (~0.18 ms per step there; compiling costs ~2.5 s, about
13,000 steps). A library already in the cache is always used."""

_WRAPPER = "dense-outputs+once"
"""How the chunk's C is wrapped (in the cache key): a library built before
the outputs were made dense (a structurally zero entry shifted the columns),
or without the single period (:meth:`Rollout.once`), is not reused."""


_SYMBOLIC = threading.RLock()
"""CasADi's symbolic work in :meth:`Rollout._build` (building the step, code
generation) one thread at a time: CasADi releases the GIL and its expression
graphs are shared between Functions. The C compiler runs outside it, so
:func:`compile_together` compiles side by side."""


def compile_together(rollouts, steps: int, threads: int | None = None) -> None:
    """Compile, side by side in up to ``threads`` threads (default
    ``processes.threads_for_side_by_side``: 1 in a worker process), each of
    ``rollouts`` that a run of ``steps`` periods would compile first (``compile
    = "auto"``, no library in the cache): a caller about to run several loop
    structures (``compare_laws``: one per law, each 3-6 s to compile for the
    Panda) pays for about half of their compiles on 2 cores instead of all of
    them in turn. The generated C is written one rollout at a time; results
    are those of compiling each when it runs. A failed compile warns and
    leaves that rollout on the virtual machine, as when it runs."""
    import concurrent.futures

    if threads is None:
        from ..processes import threads_for_side_by_side

        threads = threads_for_side_by_side()
    todo = list({id(r): r for r in rollouts if r._pending and r._steps + steps > COMPILE_AFTER}.values())
    if len(todo) < 2 or threads < 2:
        return
    with concurrent.futures.ThreadPoolExecutor(min(threads, len(todo)), thread_name_prefix="tmtcontrol-cc") as pool:
        futures = [pool.submit(r._compile, warn=False) for r in todo]
        try:
            failed = [f.result() for f in futures]
        except BaseException:       # Ctrl-C: the compiles not started are not wanted
            for f in futures:
                f.cancel()
            raise
    for text in filter(None, failed):     # here, in the rollouts' order, pointing at the caller (not a thread)
        warnings.warn(text, RuntimeWarning, stacklevel=2)


def _cpu_id() -> str:
    """Machine and CPU model: -march=native code must not be reused on another CPU."""
    model = ""
    try:
        with open("/proc/cpuinfo") as fh:
            model = next((l for l in fh if l.startswith(("model name", "flags"))), "")
    except OSError:
        pass
    return platform.machine() + platform.processor() + model



class Rollout:
    """Run ``step`` over many periods: ``run(s0, U, p) -> (S, L)``.

    Parameters
    ----------
    step : casadi.Function or callable
        ``["s","u","p"] -> ["s_next","log"]``, or a function without
        arguments that builds it (then ``structure`` is required, and the
        step is only built when it is needed: a cache miss or the virtual
        machine).
    compile : bool or "auto"
        Try to generate and compile C (needs an SX Function and a compiler).
    structure : (str, str), optional
        The step's name and a key that identifies its structure (what the
        caller knows changes the Function), used as the cache key instead of
        the Function's serialisation, so a warm start builds nothing.

    Attributes
    ----------
    how : str
        ``"compiled"`` (built now), ``"cached"`` (library reused) or ``"vm"``.
    """

    def __init__(self, step, compile: bool | str = True, chunk: int = _CHUNK,
                 structure: tuple[str, str] | None = None):
        if compile not in (True, False, "auto"):
            raise ValueError(f"compile: expected True, False or 'auto', got {compile!r}")
        built = isinstance(step, ca.Function)
        if not built and structure is None:
            raise ValueError("structure: required when step is given as a function that builds it")
        self._step, self._make = (step, None) if built else (None, step)
        self._structure = structure[1] if structure else None
        self.name = structure[0] if structure else step.name()
        self.chunk = int(chunk)
        self.ns = self.nu = self.np = self.nl = None
        if built:
            self._sizes_from(step)
        self._lib = None
        self._pending = False       # compile once enough steps have run on the virtual machine
        self._steps = 0
        self.how = "vm"
        if compile:
            if compile == "auto" and not self._cached():
                self._pending = True
            else:
                self._compile()

    @property
    def step(self) -> ca.Function:
        """The per-period Function (built on first use if it was given lazily)."""
        if self._step is None:
            self._step = self._make()
            self._sizes_from(self._step)
        return self._step

    def _sizes_from(self, step: ca.Function) -> None:
        self.ns, self.nu, self.np, self.nl = (step.size1_in(0), step.size1_in(1), step.size1_in(2),
                                              step.size1_out(1))

    @property
    def _chunk_name(self) -> str:
        return f"{self.name}_chunk"

    def _compile(self, warn: bool = True) -> str | None:
        """Load or build the library; if that fails, warn (or, without
        ``warn``, return the warning's text) and stay on the virtual machine."""
        self._pending = False
        try:
            self._load()
        except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
            if compiler() is not None:
                text = f"tmtcontrol: compiling {self.name} failed ({exc}); running on CasADi's virtual machine"
                if not warn:
                    return text
                warnings.warn(text, RuntimeWarning, stacklevel=3)
        return None

    def _cached(self) -> bool:
        return cache.find(self._library_name()) is not None

    # -- compilation --------------------------------------------------------------
    @functools.cached_property
    def _key(self) -> str:
        """Cache key from the step's structure (the caller's structure key, or
        the Function's serialisation), the flags, the CasADi version and the
        CPU: no C is generated to look up; computed once per Rollout."""
        if self._structure is not None:
            h = hashlib.sha256(b"structure:" + self._structure.encode())
        else:
            with _SYMBOLIC:
                h = hashlib.sha256(self.step.mapaccum(self._chunk_name, self.chunk).serialize().encode())
        # the optimisation level is not in the key: no level changes a result (O1_FROM)
        for part in (" ".join(_FLAGS), LEVEL or "", ca.__version__, _cpu_id(), str(self.chunk), _WRAPPER):
            h.update(part.encode())
        return h.hexdigest()[:20]

    def _library_name(self) -> str:
        return f"{self._chunk_name}_{self._key}.so"

    def _load(self):
        name = self._chunk_name
        lib = cache.find(self._library_name())
        how = "cached"
        if lib is not None and not cache.verify(lib):
            warnings.warn(f"tmtcontrol: cached library {lib} is damaged; rebuilding it", RuntimeWarning,
                          stacklevel=3)
            how = "rebuilt"
        elif lib is not None:
            self._bind(ctypes.CDLL(str(lib)), name)
            cache.mark_used(lib)
            self.how, self.library = how, lib
            return
        if compiler() is None:
            raise OSError("no C compiler")
        with cache.compile_lock(self._library_name()):
            again = cache.find(self._library_name())
            if again is not None and cache.verify(again):      # another process stored it while this one waited
                self._bind(ctypes.CDLL(str(again)), name)
                cache.mark_used(again)
                self.how, self.library = "cached", again
                return
            self._build(lib, how)

    def _build(self, lib, how):
        """Generate, compile, store and load the library (``lib``: a damaged
        cached one to replace, or None)."""
        name = self._chunk_name
        target = lib if lib is not None else cache_dir() / self._library_name()
        with _SYMBOLIC:
            acc = self.step.mapaccum(name, self.chunk)
            # named as the library is (mapaccum names its Function after the chunk's factors)
            args = acc.mx_in()
            # dense outputs: the buffers are dense, and a structurally zero entry (a monodromy row of a state
            # that is a constant, the mid-period hold's flag) would otherwise be left out of the C output
            fn = ca.Function(name, args, [ca.densify(o) for o in acc.call(args)], acc.name_in(), acc.name_out())
            one = self.step.mx_in()
            once = ca.Function(f"{name}_once", one, [ca.densify(o) for o in self.step.call(one)],
                               self.step.name_in(), self.step.name_out())
        # a private build folder under the cache, removed however this ends; the compiler is killed
        # with its children if this is interrupted, and its temporaries are in the folder's tmp/
        with cache.build_folder("cg") as build:
            with _SYMBOLIC:
                gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
                gen.add(fn)
                gen.add(once)           # one period (the step's code is generated once, for both)
                cfile = pathlib.Path(gen.generate(str(build) + os.sep))
            # the step's operations, counted in the file compiled (the chunk and the period add none: MX calls)
            level = optimisation_level(_assignments(cfile.read_text()))
            tmp_lib = build / "lib.so"
            run_compiler([compiler(), level, *_FLAGS, str(cfile), "-o", str(tmp_lib), "-lm"], build / "tmp")
            lib = self._keep(tmp_lib, target)
            # an uncached library is loaded from the build folder, which is removed
            # after loading (the mapping stays valid): nothing is left behind
            self._bind(ctypes.CDLL(str(lib)), name)
        self.how = "compiled" if how == "cached" else how
        self.library = lib

    @staticmethod
    def _keep(built: pathlib.Path, target: pathlib.Path) -> pathlib.Path:
        """Store ``built`` as ``target`` and prune its folder; if that folder
        cannot be written, in the per-user fallback folder; on a full disk,
        nowhere. Returns the path to load."""
        cache.prune_temporary()
        try:
            cache.store(built, target)
            cache.prune(target.parent, keep=(target,))
            return target
        except OSError as exc:
            full = exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
            reason = exc.strerror or str(exc)
        fallback = None if full else cache.fallback_cache()
        if fallback is not None and fallback != target.parent:
            try:
                cache.store(built, fallback / target.name)
                cache.prune(fallback, keep=(fallback / target.name,))
                warnings.warn(f"tmtcontrol: cannot write the compile cache {target.parent} ({reason}); compiled "
                              f"code is kept in {fallback} until the system clears it; set TMTCONTROL_CACHE to a "
                              "writable folder to keep it", RuntimeWarning, stacklevel=4)
                return fallback / target.name
            except OSError as exc:
                full = exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
        if full:
            warnings.warn(f"tmtcontrol: the disk holding the compile cache is full ({reason}); this run's compiled "
                          "code is not cached (free some space to keep it)", RuntimeWarning, stacklevel=4)
        else:
            warnings.warn(f"tmtcontrol: cannot write the compile cache {target.parent} ({reason}); this run's "
                          "compiled code is not cached; set TMTCONTROL_CACHE to a writable folder to keep it",
                          RuntimeWarning, stacklevel=4)
        return built

    def _bind(self, dll, name):
        ll = ctypes.c_longlong  # casadi_int

        def work_sizes(fname):
            work = getattr(dll, f"{fname}_work")
            work.argtypes = [ctypes.POINTER(ll)] * 4
            sz = [ll() for _ in range(4)]
            if work(*[ctypes.byref(x) for x in sz]) != 0:
                raise RuntimeError(f"{fname}_work failed")
            return [x.value for x in sz]

        # the work buffers serve the chunk and the single period
        sz_arg, sz_res, sz_iw, sz_w = map(max, zip(work_sizes(name), work_sizes(f"{name}_once")))
        if self.ns is None:         # the step was not built: its sizes are in the library
            rows = []
            for which, count in (("in", 3), ("out", 2)):
                sparsity = getattr(dll, f"{name}_sparsity_{which}")
                sparsity.argtypes, sparsity.restype = [ll], ctypes.POINTER(ll)
                rows += [sparsity(i)[0] for i in range(count)]
            self.ns, self.nu, self.np, _, self.nl = rows
        self._fn, self._once = (getattr(dll, f) for f in (name, f"{name}_once"))
        for fn in (self._fn, self._once):
            fn.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
            fn.restype = ctypes.c_int
        # the work buffers' sizes: each run allocates its own, so runs may go side by side in threads
        # (ctypes releases the GIL during the call; the generated code keeps no state of its own)
        self._work = (max(sz_arg, 3), max(sz_res, 2), max(sz_iw, 1), max(sz_w, 1))
        self._lib = dll

    # -- running ------------------------------------------------------------------
    def _buffers(self):
        """A call's own argument, result and work buffers (``arg, res, iw, w``)
        for the compiled chunk or period: each call allocates its own, so
        calls may go side by side in threads."""
        n_arg, n_res, n_iw, n_w = self._work
        return ((ctypes.c_void_p * n_arg)(), (ctypes.c_void_p * n_res)(), np.zeros(n_iw, dtype=np.int64),
                np.zeros(n_w))

    def once(self, s, u, p) -> tuple[np.ndarray, np.ndarray]:
        """One period ``(s_next, log)`` from ``s`` with inputs ``u`` and
        parameters ``p``: the compiled step called directly (microseconds; a
        :meth:`run` of one period computes a whole chunk), or the step on
        CasADi's virtual machine before it is compiled. Sizes as :meth:`run`;
        not counted toward compiling."""
        if self._lib is None:
            out = self.step(s, u, p)
            return np.ravel(np.array(out[0])), np.ravel(np.array(out[1]))
        s, u, p = (np.ascontiguousarray(x, dtype=float).ravel() for x in (s, u, p))
        for name, got, want in (("s", s.size, self.ns), ("u", u.size, self.nu), ("p", p.size, self.np)):
            if got != want:
                raise ValueError(f"{name}: size {got}, the step takes {want}")
        s_next, log = np.empty(self.ns), np.empty(self.nl)
        arg, res, iw, w = self._buffers()
        arg[0], arg[1], arg[2] = s.ctypes.data, u.ctypes.data, p.ctypes.data
        res[0], res[1] = s_next.ctypes.data, log.ctypes.data
        if self._once(arg, res, iw.ctypes.data, w.ctypes.data, 0) != 0:
            raise RuntimeError("compiled step failed")
        return s_next, log

    def run(self, s0, U, p) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``U.shape[1]`` periods from ``s0``.

        Returns ``S`` (ns x N, the state after each period) and ``L`` (nl x N,
        the log at the start of each period).
        """
        if self._lib is None:
            self.step                               # the virtual machine needs the Function
        s0 = np.ascontiguousarray(s0, dtype=float).ravel()
        U = np.asarray(U, dtype=float)
        U = U[None, :] if U.ndim == 1 and self.nu == 1 else U
        p = np.ascontiguousarray(p, dtype=float).ravel()
        # the compiled chunk reads exactly these sizes: another would be read past its end (review 30)
        for name, got, want in (("s0", s0.size, self.ns), ("U", U.shape[0] if U.ndim == 2 else -1, self.nu),
                                ("p", p.size, self.np)):
            if got != want:
                raise ValueError(f"{name}: {'rows' if name == 'U' else 'size'} {got if got >= 0 else U.shape}, "
                                 f"the step takes {want}")
        N = U.shape[1]
        if N < 1:
            raise ValueError("U: no period to run (0 columns)")
        self._steps += N
        if self._pending and self._steps > COMPILE_AFTER:
            self._compile()
        if self._lib is None:
            S, L = self.step.mapaccum("rollout", N)(s0, U, p)
            return np.array(S).reshape(self.ns, N), np.array(L).reshape(self.nl, N)
        C = self.chunk
        nchunks = -(-N // C)
        Upad = np.empty((self.nu, nchunks * C), order="F")
        Upad[:, :N] = U
        Upad[:, N:] = U[:, -1:]
        S = np.empty((self.ns, nchunks * C), order="F")
        # the log row by row (each field's series contiguous: a reduction along a strided row is ~15x slower,
        # issue 42), written through one chunk's buffer that stays in cache: a transposing copy of the whole
        # log afterwards costs more than the rows save
        L = np.empty((self.nl, N))
        Lbuf = np.empty((self.nl, C), order="F")
        # mapaccum's C code reads p per period (CasADi's Python call broadcasts it)
        Pblk = np.asfortranarray(np.repeat(p[:, None], C, axis=1))
        state = s0.copy()
        arg, res, iw, w = self._buffers()
        for i in range(nchunks):
            cols = slice(i * C, (i + 1) * C)
            Ui, Si = Upad[:, cols], S[:, cols]
            arg[0], arg[1], arg[2] = state.ctypes.data, Ui.ctypes.data, Pblk.ctypes.data
            res[0], res[1] = Si.ctypes.data, Lbuf.ctypes.data
            if self._fn(arg, res, iw.ctypes.data, w.ctypes.data, 0) != 0:
                raise RuntimeError("compiled rollout failed")
            L[:, i * C:min((i + 1) * C, N)] = Lbuf[:, :min(C, N - i * C)]
            state = Si[:, -1].copy()
        return S[:, :N], L
