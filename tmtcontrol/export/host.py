"""The user's compiled controller in a process of its own: a crash, an exit or a hang in their C stays there.

``tmtcontrol simulate --controller DIR`` runs C that tmtcontrol did not
write (the folder may have been edited, or be a different build). Loaded
into tmtcontrol itself, a segmentation fault in ``tmt_step`` would kill it
with no message, an ``exit(0)`` would end it silently, an endless loop would
make it deaf to Ctrl-C. So the library is loaded only here, in a small child
process (``python -I -S`` running this file: the standard library only), and
tmtcontrol talks to it over a pipe (:class:`ControllerHost`): the parameters
and the start state once, then one measurement in and one command out per
period (all little-endian doubles). tmtcontrol waits for each answer at
most :data:`STEP_BUDGET` seconds, sees the child's end (its signal or exit
status) as end of file, and kills it when it is interrupted or done. What
the C prints (stdout and stderr) never enters the protocol: the child moves
the protocol to a descriptor of its own and sends the library's stdout to
stderr, which tmtcontrol drains as it comes (the last lines are quoted in
an error message). The child starts a session of its own (a terminal's Ctrl-C reaches tmtcontrol,
which stops it) and asks the kernel to kill it when tmtcontrol dies.

Requests (one opcode byte, then the payload): ``I`` + parameters: ``tmt_init``;
``S`` + controller state: copied into the state's ``s``; ``T`` +
measurement: ``tmt_step``, answered by the return code (int32) and the
command and diagnostics; ``Q``: exit. Any other request ends the child.
"""

from __future__ import annotations

import collections
import ctypes
import os
import select
import signal
import struct
import subprocess
import sys
import threading

STEP_BUDGET = float(os.environ.get("TMTCONTROL_STEP_BUDGET", "10"))
"""Seconds tmtcontrol waits for one answer of the controller (``tmt_init`` or
one ``tmt_step``, which take microseconds): beyond it the C is taken to hang.
The environment variable ``TMTCONTROL_STEP_BUDGET`` sets it."""

SIZES = ("param", "state", "meas", "out", "arg", "res", "iw", "w")
"""The sizes (doubles or pointers) the child builds its structs with, in argv order after the library."""


def state_struct(sizes: dict):
    """The C ``tmt_state`` as a ctypes Structure for ``sizes`` (the keys of
    :data:`SIZES`): the one description of its layout, used here and by
    :class:`tmtcontrol.export.sil.CompiledController`."""
    alloc = lambda n: max(int(n), 1)                                        # noqa: E731
    return type("tmt_state", (ctypes.Structure,), {"_fields_": [
        ("s", ctypes.c_double * alloc(sizes["state"])), ("s_next", ctypes.c_double * alloc(sizes["state"])),
        ("y", ctypes.c_double * int(sizes["meas"])), ("p", ctypes.c_double * int(sizes["param"])),
        ("out", ctypes.c_double * int(sizes["out"])), ("arg", ctypes.c_void_p * alloc(sizes["arg"])),
        ("res", ctypes.c_void_p * alloc(sizes["res"])), ("iw", ctypes.c_longlong * alloc(sizes["iw"])),
        ("w", ctypes.c_double * alloc(sizes["w"]))]})


def size_mismatch(dll, structs: dict, prefix: str = "tmt") -> str | None:
    """The first of ``structs`` (C name without ``<prefix>_`` -> ctypes type)
    whose size differs in the loaded library ``dll`` (its
    ``<prefix>_sizeof_*``), said in one line; None when all agree."""
    for name, cls in structs.items():
        fn = getattr(dll, f"{prefix}_sizeof_{name}")
        fn.restype = ctypes.c_size_t
        if fn() != ctypes.sizeof(cls):
            return f"{prefix}_{name} has {fn()} bytes in the library, {ctypes.sizeof(cls)} in export.json"
    return None


class HostFault(RuntimeError):
    """The controller's process crashed, exited, hung or answered nonsense; the message is one line."""


class ControllerHost:
    """The child process holding the library ``lib`` (its structs sized by
    ``sizes``, a dict with the keys of :data:`SIZES`). Use as a context
    manager: the child is killed on leaving it."""

    def __init__(self, lib, sizes: dict, budget: float = STEP_BUDGET, prefix: str = "tmt"):
        self.sizes, self.budget, self.prefix = sizes, budget, prefix
        args = [sys.executable, "-I", "-S", os.path.abspath(__file__), str(lib), prefix,
                *(str(int(sizes[k])) for k in SIZES)]
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     start_new_session=True, close_fds=True)
        # what the C prints (its stdout is sent there too) is drained as it comes, the last lines kept for the
        # message: a chatty controller never blocks on a full pipe
        self._said: collections.deque = collections.deque(maxlen=16)
        self._drain = threading.Thread(target=self._read_stderr, daemon=True)
        self._drain.start()
        try:
            self._read(1, "starting")                  # b"r": loaded and sized
        except BaseException:
            self.close()
            raise

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        self.proc.wait()
        self._drain.join(timeout=1.0)
        for f in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            try:
                f.close()
            except OSError:
                pass

    def _read_stderr(self) -> None:
        fd = self.proc.stderr.fileno()
        try:
            while chunk := os.read(fd, 65536):
                self._said.append(chunk)
        except OSError:
            pass

    # -- requests -------------------------------------------------------------------------
    def init(self, params: bytes) -> None:
        self._send(b"I" + params)
        self._read(1, f"{self.prefix}_init")

    def set_state(self, s: bytes) -> None:
        self._send(b"S" + s)
        self._read(1, "setting the state")

    def step(self, meas: bytes) -> tuple[int, bytes]:
        self._send(b"T" + meas)
        data = self._read(4 + 8 * self.sizes["out"], f"{self.prefix}_step")
        return struct.unpack("<i", data[:4])[0], data[4:]

    # -- the pipe ---------------------------------------------------------------------------
    def _send(self, data: bytes) -> None:
        try:
            self.proc.stdin.write(data)
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise HostFault(self._ended(f"{self.prefix}_step")) from None

    def _read(self, n: int, what: str) -> bytes:
        out, fd = b"", self.proc.stdout.fileno()
        while len(out) < n:
            ready, _, _ = select.select([fd], [], [], self.budget)
            if not ready:
                self.close()
                raise HostFault(f"{what} did not return within {self.budget:g} s (an endless loop?); "
                                "the controller's process was stopped")
            chunk = os.read(fd, n - len(out))
            if not chunk:
                raise HostFault(self._ended(what))
            out += chunk
        return out

    def _ended(self, what: str) -> str:
        try:
            rc = self.proc.wait(timeout=self.budget)
        except subprocess.TimeoutExpired:
            self.close()
            rc = self.proc.returncode
        self._drain.join(timeout=1.0)
        said = b"".join(self._said)[-4000:]
        said = " ".join(said.decode("utf-8", "replace").split())[-200:]
        if rc is not None and rc < 0:
            try:
                name = signal.Signals(-rc).name
            except ValueError:
                name = f"signal {-rc}"
            how = f"crashed ({name})"
        else:
            how = f"ended (exit status {rc})"
        return f"the controller {how} in {what}" + (f": {said}" if said else "")


# -- the child ------------------------------------------------------------------------------------

def _die_with_parent() -> None:
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)           # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


def _serve(lib: str, prefix: str, sizes: list[int]) -> int:
    # the protocol gets a descriptor of its own; the C library's stdout (printf) goes to stderr, so
    # nothing the user's code prints can enter the command stream
    proto = os.dup(1)
    os.dup2(2, 1)

    size = dict(zip(SIZES, sizes))
    n_p, n_s, n_y = size["param"], size["state"], size["meas"]
    Params, State = ctypes.c_double * n_p, state_struct(size)
    Meas, Out = ctypes.c_double * n_y, ctypes.c_double * size["out"]
    dll = ctypes.CDLL(lib)
    wrong = size_mismatch(dll, {"params": Params, "state": State, "measurement": Meas, "command": Out}, prefix)
    if wrong:
        print(wrong, file=sys.stderr)
        return 4
    step, init = getattr(dll, f"{prefix}_step"), getattr(dll, f"{prefix}_init")
    step.argtypes, step.restype = [ctypes.c_void_p] * 4, ctypes.c_int
    init.argtypes = [ctypes.c_void_p] * 2
    params, state, meas, out = Params(), State(), Meas(), Out()
    rd, wr = sys.stdin.buffer, os.fdopen(proto, "wb")
    wr.write(b"r")
    wr.flush()
    while True:
        op = rd.read(1)
        if op == b"I":
            ctypes.memmove(params, rd.read(8 * n_p), 8 * n_p)
            init(ctypes.byref(params), ctypes.byref(state))
            wr.write(b"k")
        elif op == b"S":
            ctypes.memmove(state.s, rd.read(8 * n_s), 8 * n_s)
            wr.write(b"k")
        elif op == b"T":
            ctypes.memmove(meas, rd.read(8 * n_y), 8 * n_y)
            rc = step(ctypes.byref(params), ctypes.byref(state), ctypes.byref(meas), ctypes.byref(out))
            wr.write(struct.pack("<i", rc) + bytes(out))
        else:                                            # Q, or the parent is gone
            return 0
        wr.flush()


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)        # tmtcontrol handles Ctrl-C and stops this process
    _die_with_parent()
    sys.exit(_serve(sys.argv[1], sys.argv[2], [int(a) for a in sys.argv[3:]]))
