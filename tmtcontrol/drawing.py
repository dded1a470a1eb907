"""Writing figures as PNG files (:func:`save_figures`), here or by two
processes forked before the work that feeds them (:class:`FigureWorkers`).

Importing matplotlib costs about 0.3-0.4 s and drawing a simulation's four
PNGs about as much again, all on one core. :class:`FigureWorkers`, created
first thing, forks a process that imports matplotlib and the figure module
while this one imports CasADi and simulates; that process then forks a
second, which inherits the imports. Given the data, both draw, taking the
figures one at a time from a shared queue (one byte per figure in a pipe),
while this process writes its tables. The data reach them through a file
without a name (``memfd``) opened before the fork: this process writes it
at once and tells each worker its length, so a worker still importing never
holds up this process, nor does this process's next work (the tables, which
hold the interpreter's lock for tens of milliseconds) hold up the data.
The two run in a process group of their own, so they are killed together
when this process stops waiting for them (an error, Ctrl-C, SIGTERM); they
never write outside the folder given.

On platforms without a safe ``fork`` (anything but Linux) or with
``processes=0``, the figures are drawn here when their result is asked for:
the same files either way.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import traceback
from collections.abc import Sequence

__all__ = ["save_figures", "FigureWorkers", "Drawing", "FigureProcessError"]


def save_figures(makers, data, folder, dpi: int = 120) -> list:
    """Write ``NAME.png`` for each ``(NAME, make)`` of ``makers``, the figure
    being ``make(data)``, in the house style, into ``folder`` (replacing a
    file of that name, as ``savefig`` does; the commands write into their
    own fresh output folders); return the paths."""
    import pathlib

    from .plotstyle import plain_log_labels, styled

    folder = pathlib.Path(folder)
    out = []
    for name, make in makers:
        path = folder / f"{name}.png"
        with styled():                      # the package's one figure style
            # zlib level 1, not Pillow's 6: the four simulation figures' drawing and encoding took 0.46 s of CPU
            # against 0.54 s (median of 6, 2026-12-06) for files 8 % larger (311 kB against 288 kB)
            plain_log_labels(make(data)).savefig(path, dpi=dpi, pil_kwargs={"compress_level": 1})
        out.append(path)
    return out


class FigureProcessError(RuntimeError):
    """A figure process failed: its traceback, or how it ended."""


def can_fork() -> bool:
    return sys.platform.startswith("linux") and hasattr(os, "fork")


def read_all(fd: int) -> bytes:
    chunks = []
    while chunk := os.read(fd, 1 << 20):
        chunks.append(chunk)
    return b"".join(chunks)


def write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


class FigureWorkers:
    """Processes that import ``module`` now and draw its figures later.

    Parameters
    ----------
    module : str
        The module whose functions draw the figures (each takes the data and
        returns a matplotlib Figure); imported by the workers at once.
    processes : int
        How many processes draw (default 2, one per core of the reference
        machine); 0 draws in this process when the result is asked for.

    Use as a context manager: leaving it stops the workers that are still
    running. :meth:`draw` hands them the data and returns a :class:`Drawing`.
    Made for the command line, which forks before it starts any thread; in
    a process that already runs threads (a notebook, a server) forking is
    unsafe: use ``processes=0`` there.
    """

    def __init__(self, module: str, processes: int = 2):
        if isinstance(processes, bool) or not isinstance(processes, int) or not 0 <= processes <= 8:
            raise ValueError(f"processes: an integer from 0 to 8, got {processes!r}")
        self.module = module
        self._pid: int | None = None
        self._jobs: list[int] = []        # write ends: the data's length, per worker
        self._results: list[int] = []     # read ends: one result message per worker
        self._tokens: int | None = None   # write end of the shared queue
        self._data: int | None = None     # the file the data are written to, shared with the workers
        if processes and can_fork():
            self._start(processes)

    def _start(self, processes: int) -> None:
        jobs = [os.pipe() for _ in range(processes)]
        results = [os.pipe() for _ in range(processes)]
        tokens = os.pipe()
        self._data = _unnamed_file()
        pid = os.fork()
        if pid == 0:                                          # pragma: no cover - runs in the worker
            _worker(self.module, jobs, results, tokens, self._data)
        self._pid = pid
        os.close(tokens[0])
        self._tokens = tokens[1]
        for (r, w), (rr, rw) in zip(jobs, results):
            os.close(r)
            os.close(rw)
            self._jobs.append(w)
            self._results.append(rr)

    @property
    def forked(self) -> bool:
        """True if the figures are drawn by forked processes."""
        return self._pid is not None

    def draw(self, figures: Sequence[tuple[str, str]], data, folder) -> Drawing:
        """Start writing ``folder/NAME.png`` for each ``(NAME, FUNCTION)`` of
        ``figures`` (longest to draw first), the figure being
        ``module.FUNCTION(data)``; ``data`` must pickle with what the
        workers have imported. Once per instance."""
        figures = list(figures)
        if self.forked:
            if self._tokens is None:
                raise RuntimeError("FigureWorkers.draw: the workers have been given their figures already")
            if len(figures) > 256:                  # a figure's index is one byte of the shared queue
                raise ValueError(f"figures: at most 256 per drawing, got {len(figures)}")
            write_all(self._tokens, bytes(range(len(figures))))      # the shared queue
            os.close(self._tokens)
            self._tokens = None
            message = pickle.dumps((figures, data, str(folder)), protocol=pickle.HIGHEST_PROTOCOL)
            # the data into the shared file, then its length (8 bytes: a pipe takes them at once) to each worker
            try:
                write_all(self._data, message)
            except OSError as exc:       # no memory (or, without memfd, no room in the temporary folder)
                self.stop()
                raise FigureProcessError(f"the figures' data could not be handed to the figure processes: {exc}") \
                    from exc
            os.close(self._data)
            self._data = None
            jobs, self._jobs = self._jobs, []
            for fd in jobs:
                try:
                    write_all(fd, len(message).to_bytes(8, "little"))
                except OSError:          # the worker is gone (stopped, or failed: its result says)
                    pass
                finally:
                    os.close(fd)
        return Drawing(self, figures, data, folder)

    def stop(self) -> None:
        """Kill the workers unless they have finished, and release their
        pipes. Nothing is written by them after this returns."""
        if self._pid is None:
            return
        try:
            os.killpg(self._pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        for fd in [*self._jobs, *self._results, *(fd for fd in (self._tokens, self._data) if fd is not None)]:
            os.close(fd)
        self._jobs, self._results, self._tokens, self._data = [], [], None, None
        try:
            os.waitpid(self._pid, 0)
        except ChildProcessError:
            pass
        self._pid = None

    def __enter__(self) -> FigureWorkers:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


class Drawing:
    """Figures being drawn; :meth:`result` waits for their paths."""

    def __init__(self, workers: FigureWorkers, figures: list[tuple[str, str]], data, folder):
        self._workers, self._figures, self._data, self._folder = workers, figures, data, folder
        self._paths: list | None = None

    def cancel(self) -> None:
        """Stop the workers unless they have finished (a no-op after
        :meth:`result`): nothing is written into the folder after this."""
        self._workers.stop()

    def result(self) -> list:
        """The paths written, in the order of ``figures`` (waits for them
        once; the same list after). Raises :class:`FigureProcessError` if a
        worker failed."""
        if self._paths is None:
            self._paths = self._wait()
        return self._paths

    def _wait(self) -> list:
        import importlib
        import pathlib

        w = self._workers
        if not w.forked:
            module = importlib.import_module(w.module)
            return save_figures([(n, getattr(module, f)) for n, f in self._figures], self._data, self._folder)
        written, errors = {}, []
        for fd in w._results:
            raw = read_all(fd)
            if not raw:
                errors.append("a figure process ended without a result")
                continue
            status, value = pickle.loads(raw)
            if status == "ok":
                written.update(value)
            else:
                errors.append(value)
        w.stop()
        if errors:
            raise FigureProcessError("drawing the figures failed:\n" + "\n".join(errors))
        missing = [n for n, _ in self._figures if n not in written]
        if missing:
            raise FigureProcessError(f"figures not drawn: {', '.join(missing)}")
        return [pathlib.Path(written[n]) for n, _ in self._figures]


def _unnamed_file() -> int:
    """A descriptor of a file without a name (Linux's ``memfd_create``;
    where that is refused, an unnamed temporary file): its data live while a
    process holds it open and vanish with the last, however it ends."""
    try:
        return os.memfd_create("tmtcontrol-figures", os.MFD_CLOEXEC)
    except (AttributeError, OSError):
        import tempfile

        with tempfile.TemporaryFile() as f:
            return os.dup(f.fileno())


def read_at(fd: int, n: int) -> bytes:
    """``n`` bytes of the file ``fd`` from its start (``os.pread``, which
    leaves the offset it shares with the other processes alone)."""
    chunks, got = [], 0
    while got < n:
        chunk = os.pread(fd, n - got, got)
        if not chunk:
            raise EOFError(f"the figures' data end at {got} of {n} bytes")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def _worker(module, jobs, results, tokens, data):         # pragma: no cover - runs in the worker
    """The first worker: own process group, import, fork the second, draw."""
    code = 1
    try:
        os.setpgid(0, 0)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_DFL)
        signal.signal(signal.SIGCHLD, signal.SIG_IGN)     # the second worker is reaped by the kernel
        os.close(tokens[1])
        for (r, w), (rr, rw) in zip(jobs, results):
            os.close(w)
            os.close(rr)
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")    # small arrays: no BLAS threads to fork
        try:
            import importlib

            for name in (module, "tmtcontrol.plotstyle", "matplotlib.style"):   # before the fork: both have them
                importlib.import_module(name)
        except BaseException:
            _report(results[0][1], ("error", traceback.format_exc()))
            os._exit(1)
        me = 0
        for i in range(1, len(jobs)):
            if os.fork() == 0:
                me = i
                break
        for i, ((r, _), (_, rw)) in enumerate(zip(jobs, results)):
            if i != me:
                os.close(r)
                os.close(rw)
        code = _draw(module, jobs[me][0], results[me][1], tokens[0], data)
    finally:
        os._exit(code)


def _draw(module, job_fd, result_fd, token_fd, data_fd) -> int:   # pragma: no cover - runs in the worker
    """Read the job (the length of the data in ``data_fd``), draw the
    figures this process takes from the queue, report ``("ok", {name:
    path})`` or ``("error", traceback)``."""
    raw = read_all(job_fd)
    if not raw:                                              # nothing to draw: the caller stopped
        return 0
    try:
        import importlib

        figures, data, folder = pickle.loads(read_at(data_fd, int.from_bytes(raw, "little")))
        functions = importlib.import_module(module)
        written = {}
        while token := os.read(token_fd, 1):
            name, function = figures[token[0]]
            written[name] = str(save_figures([(name, getattr(functions, function))], data, folder)[0])
    except BaseException:
        _report(result_fd, ("error", traceback.format_exc()))
        return 1
    _report(result_fd, ("ok", written))
    return 0


def _report(fd: int, message) -> None:                     # pragma: no cover - runs in the worker
    try:
        write_all(fd, pickle.dumps(message))
        os.close(fd)
    except OSError:
        pass
