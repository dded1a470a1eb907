"""Reading the user's text files within bounds: scenario and sweep TOML, stiffness and height tables.

A file is opened without blocking and checked before it is read (a folder, a
FIFO, a device or a file over :data:`MAX_INPUT_BYTES` is refused at once);
TOML is parsed with a bound on dotted keys (:func:`parse_toml`). Errors are
one line naming the file and what it should have been.
"""

from __future__ import annotations

import pathlib
import re
import tomllib

__all__ = ["MAX_INPUT_BYTES", "InputFileError", "read_text_file", "read_toml", "MAX_KEY_PARTS", "parse_toml"]


MAX_INPUT_BYTES = 16 * 2**20
"""The largest scenario, sweep or stiffness-table file read (16 MiB): anything
larger is refused before it is read."""


class InputFileError(ValueError):
    """An input file that cannot be read as text; the message is the reason,
    without the file's name (callers say which file and what it should be)."""


def read_text_file(path: str | pathlib.Path, max_bytes: int = MAX_INPUT_BYTES) -> str:
    """The text of the regular file ``path`` (UTF-8; a leading UTF-8 byte-order
    mark, as Windows Notepad and Excel's "CSV UTF-8" write, is dropped).

    The file is opened without blocking and checked before anything is read:
    a folder, a FIFO, a device (``/dev/zero``), a socket, or a file larger than
    ``max_bytes`` raise :class:`InputFileError` at once (a FIFO never blocks)."""
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise InputFileError("no such file") from None
    except OSError as exc:
        raise InputFileError(f"cannot read ({exc.strerror})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise InputFileError("is a folder")
        if not stat.S_ISREG(st.st_mode):
            what = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode)
                    or stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "special")
            raise InputFileError(f"not a regular file ({what})")
        if st.st_size > max_bytes:
            raise InputFileError(f"{st.st_size / 2**20:.1f} MiB, larger than the {max_bytes / 2**20:g} MiB limit")
        chunks, size = [], 0
        while size <= max_bytes:            # a file growing while it is read stops at the limit too
            chunk = os.read(fd, min(max(st.st_size + 1, 65536), 2**20, max_bytes + 1 - size))   # no 16 MiB buffer
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > max_bytes:
            raise InputFileError(f"larger than the {max_bytes / 2**20:g} MiB limit")
    except OSError as exc:
        raise InputFileError(f"cannot read ({exc.strerror})") from None
    finally:
        os.close(fd)
    try:
        return b"".join(chunks).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"not UTF-8 text (byte {exc.start})") from None


def read_toml(path: pathlib.Path, what: str, error: type[Exception]) -> dict:
    """Parse the TOML file ``path``; every failure (missing, a folder, not a
    regular file, larger than :data:`MAX_INPUT_BYTES`, not UTF-8, unreadable,
    malformed) raises ``error`` naming the file and ``what`` it should have
    been. A UTF-8 byte-order mark is accepted."""
    src = str(path)
    try:
        text = read_text_file(path)
    except InputFileError as exc:
        reason = str(exc)
        if reason == "no such file":
            raise error(f"{src}: no such {what} file") from None
        if reason == "is a folder":
            raise error(f"{src}: is a folder, expected a {what} TOML file") from None
        if reason.startswith("not a regular file"):
            raise error(f"{src}: {reason}, expected a {what} TOML file") from None
        raise error(f"{src}: {reason}" + (f" of a {what} file" if "limit" in reason else "")) from None
    try:
        return parse_toml(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{src}: malformed TOML ({exc})") from None
    except InputFileError as exc:
        raise error(f"{src}: {exc}") from None


MAX_KEY_PARTS = 64
"""The most parts a dotted TOML key may have (scenario and sweep keys have at
most five): tomllib keeps every prefix of a dotted key, memory quadratic in
its length (10,000 parts took 450 MB)."""

_KEY_PART = r"""(?:[A-Za-z0-9_-]++|"[^"\n]*+"|'[^'\n]*+')"""
_LONG_KEY = re.compile(r"(?<![A-Za-z0-9_-])" + _KEY_PART + r"(?:[ \t]*+\.[ \t]*+" + _KEY_PART + r"){%d}"
                       % MAX_KEY_PARTS)


def parse_toml(text: str) -> dict:
    """``tomllib.loads(text)`` within bounds: a dotted key of more than
    :data:`MAX_KEY_PARTS` parts (found by a linear scan before parsing; a run
    inside a string or comment counts too, conservatively) and arrays or
    tables nested past the parser's recursion raise :class:`InputFileError`
    with the reason; malformed TOML raises ``tomllib.TOMLDecodeError``."""
    long_key = _LONG_KEY.search(text)
    if long_key:
        raise InputFileError(f"a key of more than {MAX_KEY_PARTS} dotted parts (line "
                             f"{text.count(chr(10), 0, long_key.start()) + 1}); no key is that deep")
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise InputFileError("arrays or tables nested too deeply") from None
