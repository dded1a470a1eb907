"""The ``[environment]`` section: the surface (the plane of Fig. 2, a sphere or a cylinder), its contact damping and the stiffness profile k_e(t) (Fig. 3)."""

from __future__ import annotations

import csv
import functools
import io
import math
import pathlib
from typing import Annotated, Any, Literal, Union

from pydantic import Field, model_serializer, model_validator

from .fields import MAX_STIFFNESS, MIN_STIFFNESS, F, NonNeg, Section, Stiff, num, tag_default
from .textfiles import InputFileError, read_text_file

__all__ = ["SHAPES", "read_height_grid", "large_radius_note", "PiecewiseConstantStiffness", "PiecewiseLinearStiffness",
           "SinusoidalStiffness", "TableStiffness", "StiffnessProfile", "read_stiffness_table", "EnvironmentSettings"]


class PiecewiseConstantStiffness(Section):
    """``values[i]`` on ``[i, i+1) * segment``, the last value held (Fig. 3)."""
    kind: Literal["piecewise_constant"] = "piecewise_constant"
    values: tuple[Stiff, ...] = Field((5e3, 2e4, 2e3, 1e4), min_length=1,
                                    description="stiffness of each segment [N/m]", json_schema_extra={"unit": "N/m"})
    segment: float = num(0.0, "s", "segment length, 0 (= the trajectory period) or at least 10 control "
                         "periods", ge=0)


class PiecewiseLinearStiffness(Section):
    """Linear interpolation through (``times``, ``values``), held outside."""
    kind: Literal["piecewise_linear"] = "piecewise_linear"
    times: tuple[NonNeg, ...] = Field(..., min_length=1, description="knot times, strictly increasing [s]",
                                      json_schema_extra={"unit": "s"})
    values: tuple[Stiff, ...] = Field(..., min_length=1, description="stiffness at the knots [N/m]",
                                    json_schema_extra={"unit": "N/m"})

    @model_validator(mode="after")
    def _knots(self):
        if len(self.times) != len(self.values):
            raise ValueError(f"times: needs one time per value ({len(self.values)}), got {len(self.times)}")
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ValueError(f"times: must be strictly increasing, got {list(self.times)}")
        return self


class SinusoidalStiffness(Section):
    """``mean + amplitude sin(2 pi t / period)``."""
    kind: Literal["sinusoidal"] = "sinusoidal"
    mean: float = num(1e4, "N/m", "mean stiffness", gt=0, le=MAX_STIFFNESS)
    amplitude: float = num(5e3, "N/m", "amplitude, < mean so that k_e stays > 0", ge=0)
    period: float = num(4.0, "s", "period, at least 10 control periods", gt=0)

    @model_validator(mode="after")
    def _positive(self):
        if self.amplitude >= self.mean:
            raise ValueError(f"amplitude: must be < mean ({self.mean:g}) so that k_e stays > 0, "
                             f"got {self.amplitude:g}")
        return self


class TableStiffness(Section):
    """A CSV file of ``t, k_e`` rows (s, N/m), linear interpolation. A header
    row (two cells) is allowed only if it holds no number; a relative path is
    relative to the scenario file."""
    kind: Literal["table"] = "table"
    file: str = Field(..., min_length=1, description="CSV file of t, k_e rows")

    @model_validator(mode="after")
    def _readable(self):
        read_stiffness_table(self.file)
        return self


StiffnessProfile = Annotated[
    Union[PiecewiseConstantStiffness, PiecewiseLinearStiffness, SinusoidalStiffness, TableStiffness],
    tag_default("piecewise_constant"), Field(discriminator="kind")]


def read_stiffness_table(path: str | pathlib.Path) -> tuple[Any, Any]:
    """Read and validate a CSV table of ``t, k_e`` rows (s, N/m). A first row
    of two cells with no number in them is a header; any other malformed row
    is an error."""
    import numpy as np

    try:
        text = read_text_file(path)
    except InputFileError as exc:
        reason = str(exc)
        if reason == "no such file":
            raise ValueError(f"file: no such file {str(path)!r}") from None
        if reason == "is a folder":
            raise ValueError(f"file: {str(path)!r} is a folder, expected a CSV file") from None
        if reason.startswith("not UTF-8"):
            raise ValueError(f"file: {str(path)!r} is not UTF-8 text") from None
        raise ValueError(f"file: {str(path)!r}: {reason}") from None
    rows = [r for r in csv.reader(io.StringIO(text, newline=""))
            if r and "".join(r).strip() and not r[0].lstrip().startswith("#")]

    def number(cell):
        try:
            return float(cell)
        except ValueError:
            return None

    data = []
    for i, row in enumerate(rows):
        vals = [number(c) for c in row]
        if len(row) == 2 and None not in vals:
            data.append(vals)
        elif i == 0 and len(row) == 2 and all(v is None for v in vals):
            continue  # header: two cells, no number in them ('0;5000', another delimiter, is a broken row)
        else:
            shown = repr(row)
            if len(shown) > 200:            # one short line, whatever the row
                shown = f"{shown[:120]}... ({len(row)} fields)"
            raise ValueError(f"file: row {i + 1} of {str(path)!r} is not 't, k_e' numbers: {shown}")
    if not data:
        raise ValueError(f"file: no data rows in {str(path)!r}")
    arr = np.array(data)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"file: non-finite value in {str(path)!r}")
    # the bounds of the other profiles' values and knot times (review 23: 1e-4 N/m and t = -1 s were accepted)
    if np.any(arr[:, 1] < MIN_STIFFNESS):
        raise ValueError(f"file: stiffness must be >= {MIN_STIFFNESS:g} N/m in {str(path)!r}")
    if np.any(arr[:, 0] < 0):
        raise ValueError(f"file: times must be >= 0 s in {str(path)!r}")
    if np.any(arr[:, 1] > MAX_STIFFNESS):
        raise ValueError(f"file: stiffness must be <= {MAX_STIFFNESS:g} N/m in {str(path)!r}")
    if np.any(np.diff(arr[:, 0]) <= 0):
        raise ValueError(f"file: times must be strictly increasing in {str(path)!r}")
    return arr[:, 0], arr[:, 1]


SHAPES = ("plane", "sphere", "cylinder", "heightmap")
"""The surface's shapes (:mod:`tmtcontrol.surface`)."""


MAX_GRID = 256
"""Most points along each axis of a height map (its heights are constants of the compiled loop)."""


def read_height_grid(path: str | pathlib.Path):
    """Read and validate a height map: a CSV of rows of numbers (a first row
    with no number in it is a header) or a NumPy ``.npy`` file, a 2-D grid of
    at least 4 x 4 and at most :data:`MAX_GRID` points along each axis, every
    height finite (m). Cached by the file's path, size and modification time."""
    import os

    try:
        st = os.stat(path)
    except OSError:
        raise ValueError(f"heightmap: no such file {str(path)!r}") from None
    return _read_height_grid(str(path), st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=8)
def _read_height_grid(path: str, size: int, mtime_ns: int):
    import numpy as np

    from .textfiles import MAX_INPUT_BYTES

    if path.lower().endswith(".npy"):
        import os
        import stat

        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            raise ValueError(f"heightmap: {path!r} is not a regular file")
        if st.st_size > MAX_INPUT_BYTES:
            raise ValueError(f"heightmap: {path!r} is larger than the {MAX_INPUT_BYTES / 2**20:g} MiB limit")
        with open(path, "rb") as fh:
            magic = fh.read(6)
        if magic != b"\x93NUMPY":      # NumPy would read it as a pickle and say so (review 23: text named .npy)
            raise ValueError(f"heightmap: {path!r} is not a NumPy .npy file (no .npy header; a CSV file of "
                             "heights needs another extension)")
        try:
            arr = np.load(path, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            reason = str(exc).split(". ")[0].strip().rstrip(".")
            raise ValueError(f"heightmap: {path!r} is not a readable NumPy .npy array ({reason})") from None
        if arr.dtype.kind not in "fiu":
            raise ValueError(f"heightmap: {path!r} holds {arr.dtype}, expected numbers")
        arr = arr.astype(float)
    else:
        try:
            text = read_text_file(path)
        except InputFileError as exc:
            raise ValueError(f"heightmap: {path!r}: {exc}") from None
        rows = [r for r in csv.reader(io.StringIO(text, newline=""))
                if r and "".join(r).strip() and not r[0].lstrip().startswith("#")]
        data = []
        for i, row in enumerate(rows):
            try:
                data.append([float(c) for c in row])
            except ValueError:
                if i == 0 and not any(_is_number(c) for c in row):
                    continue          # header
                # review 65: numpy.savetxt's default spaces read as "not numbers", with no word of the delimiter
                spaced = any(";" in c or "\t" in c or " " in c.strip() for c in row)
                empty = any(not c.strip() for c in row)
                raise ValueError(f"heightmap: row {i + 1} of {path!r} is not comma-separated numbers"
                                 + (" (spaces, tabs or semicolons between them: write commas, e.g. "
                                    "numpy.savetxt(FILE, heights, delimiter=','))" if spaced else
                                    " (an empty cell: a trailing comma?)" if empty else "")) from None
        if not data or len({len(r) for r in data}) != 1:
            raise ValueError(f"heightmap: {path!r} must be rows of the same number of heights")
        arr = np.array(data)
    if arr.ndim != 2:
        raise ValueError(f"heightmap: {path!r} must be a 2-D grid, got {arr.ndim} dimension(s)")
    if min(arr.shape) < 4 or max(arr.shape) > MAX_GRID:
        raise ValueError(f"heightmap: {path!r} must have 4 to {MAX_GRID} points along each axis, "
                         f"got {arr.shape[0]} x {arr.shape[1]}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"heightmap: {path!r} holds a height that is not finite (NaN or inf)")
    arr.setflags(write=False)
    return arr


def _is_number(cell: str) -> bool:
    try:
        float(cell)
        return True
    except ValueError:
        return False


LARGE_RADIUS = 10.0
"""A radius (m) above which :meth:`EnvironmentSettings.unit_notes` asks
whether it was meant in millimetres (valid: a large part is nearly a plane)."""


MAX_GRID_SPACING = 1.0
"""The largest height map grid spacing (m): a wider cell than an arm's reach
is millimetres written as metres (review 43)."""


STEEP_MAP = 1.0
"""The slope between neighbouring heights of a map (rise over run) from
which :meth:`EnvironmentSettings.unit_notes` asks whether the heights are
in millimetres (45 degrees: a part the tool follows at that tilt is
possible, not usual)."""


def steep_map_note(path, spacing) -> str | None:
    """The note for a height map whose neighbouring heights rise more than
    :data:`STEEP_MAP` times the grid spacing (``environment.grid_spacing``,
    one number or ``(du, dv)``), naming its span and steepest slope and the
    millimetre reading; None otherwise (or for a map that
    cannot be read: its refusal is the validator's)."""
    import numpy as np

    try:
        h = read_height_grid(path)
    except ValueError:
        return None
    slope = max(float(np.max(np.abs(np.diff(h, axis=a)))) / d for a, d in enumerate(spacing_pair(spacing)))
    if not slope >= STEEP_MAP:
        return None
    span = float(np.ptp(h))
    return (f"environment.heightmap: heights spanning {span:.4g} m rise up to {slope:.3g} times the grid spacing "
            f"between neighbouring points (45 degrees or steeper); if the heights are in millimetres, divide "
            "them by 1000 (SI units: m)")


def large_radius_note(radius) -> str | None:
    """The note for a sphere's or cylinder's radius (m) above
    :data:`LARGE_RADIUS`, naming its sag 10 cm from the centre and the
    millimetre reading; None for a smaller radius or none."""
    if radius is None or isinstance(radius, bool) or not isinstance(radius, (int, float)) or \
            not LARGE_RADIUS < radius < math.inf:
        return None
    sag = 0.1 ** 2 / (radius + math.sqrt(radius ** 2 - 0.1 ** 2))    # R - sqrt(R^2 - 0.1^2)
    return (f"environment.radius = {radius:g} m: a part this large is within {sag * 1e6:.3g} µm of its tangent "
            f"plane 10 cm from the path's centre; if the radius is in millimetres, write {radius / 1000:g} "
            "(SI units: m)")


Spacing = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0, le=MAX_GRID_SPACING)]


def spacing_pair(spacing) -> tuple[float, float]:
    """``(du, dv)`` (m) of ``environment.grid_spacing``: one number for both
    axes, or the pair itself."""
    if isinstance(spacing, (int, float)):
        return float(spacing), float(spacing)
    du, dv = spacing
    return float(du), float(dv)


def spacing_words(spacing) -> str:
    """``environment.grid_spacing`` as a message writes it: ``0.01 m`` or
    ``0.01 x 0.02 m``."""
    du, dv = spacing_pair(spacing)
    return f"{du:g} m" if du == dv else f"{du:g} x {dv:g} m"


def _spacing_problem(value) -> str | None:
    """What is wrong with a raw ``grid_spacing`` (one line, without the key),
    or None: checked before the schema's union, whose own errors name its
    branches, and with the millimetre reading where it is too large."""
    def number(x) -> bool:
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    if value is None:
        return None
    values = list(value) if isinstance(value, (list, tuple)) else [value]
    if not (number(value) or (isinstance(value, (list, tuple)) and len(values) == 2 and all(map(number, values)))):
        return f"expected a number or a list of 2 numbers [du, dv] (m), got {value!r}"
    for x in values:
        if not math.isfinite(x):
            return f"must be finite, got {value!r}"
        if not x > 0:
            return f"must be > 0, got {value!r}"
        if not x <= MAX_GRID_SPACING:
            return (f"must be <= {MAX_GRID_SPACING:g}, got {value!r}: a cell wider than an arm's reach; if the "
                    "spacing is in millimetres, divide it by 1000 (SI units: m)")
    return None


class EnvironmentSettings(Section):
    """The surface and its unilateral spring contact, ``f_e = max(0, k_e(t) d +
    damping d')`` while the penetration d > 0. The tilted plane (Fig. 2) by
    default: it passes through ``trajectory.center``; its outward normal is
    base z rotated by ``tilt_deg`` about base y. A sphere or cylinder of
    ``radius`` touches that plane at ``trajectory.center`` (the plane is its
    tangent plane there), the tool on its ``side``; a cylinder's axis lies
    along ``axis`` (default task axis 2)."""
    shape: Literal["plane", "sphere", "cylinder", "heightmap"] = Field("plane", description=(
        "the surface's shape: plane, sphere, cylinder or heightmap (touching the plane of tilt_deg/normal at "
        "trajectory.center)"))
    # at most 1e9 m (a part that flat is its tangent plane to 1e-11 m over 10 cm; review 13: 1e300 overflowed)
    radius: float | None = Field(None, description="sphere's or cylinder's radius [m]", allow_inf_nan=False,
                                 strict=True, gt=0, le=1e9, json_schema_extra={"unit": "m"})
    side: Literal["outside", "inside"] | None = Field(None, description=(
        "sphere or cylinder: the tool works on the outside (a dome, a pipe) or the inside (a bowl, a bore); "
        "default outside"))
    axis: tuple[F, F, F] | None = Field(None, description=(
        "cylinder: unit direction of its axis, base frame, perpendicular to the normal; default task axis 2"),
        json_schema_extra={"unit": "1"})
    heightmap: str | None = Field(None, min_length=1, description=(
        "heightmap: a CSV (rows of numbers) or .npy file of heights [m] along the outward normal, rows along "
        "task axis 1, columns along task axis 2, the grid centred on trajectory.center"))
    grid_spacing: Spacing | tuple[Spacing, Spacing] | None = Field(None, description=(
        "heightmap: the grid's spacing [m], one number or [du, dv] (along task axes 1 and 2: rows and columns), "
        "at most 1 m (a wider cell than an arm's reach is a unit mistake: millimetres written as metres)"),
        json_schema_extra={"unit": "m"})
    tilt_deg: float = num(45.0, "deg", "tilt of the plane (or a curved part's tangent plane at "
                          "trajectory.center) about the base y axis (the shorthand for the inward normal "
                          "(sin t, 0, -cos t); not used when normal is set)", ge=-89.0, le=89.0)
    normal: tuple[F, F, F] | None = Field(None, description=(
        "inward unit normal of the plane (pointing into the surface), base frame, or of a curved part's "
        "tangent plane at trajectory.center; default: from tilt_deg"), json_schema_extra={"unit": "1"})
    point: tuple[F, F, F] | None = Field(None, description=(
        "a point of the plane, base frame; default: trajectory.center (the circle's centre must lie on the "
        "plane)"), json_schema_extra={"unit": "m"})
    damping: float = num(0.0, "N s/m", "contact damping", ge=0, le=1e6)
    stiffness: StiffnessProfile = Field(default_factory=PiecewiseConstantStiffness,
                                        description="stiffness profile k_e(t), a table with its kind")

    @model_serializer(mode="wrap")
    def _without_unused_tilt(self, handler):
        # with a normal, the plane is the normal's: the shorthand is left out of every dump (TOML,
        # summary.json, a replaced copy), so it never comes back as an explicit, contradicting value
        d = handler(self)
        if isinstance(d, dict) and d.get("normal") is not None:
            d.pop("tilt_deg", None)
        return d

    @model_validator(mode="before")
    @classmethod
    def _grid_spacing(cls, data):
        if isinstance(data, dict) and (problem := _spacing_problem(data.get("grid_spacing"))):
            raise ValueError(f"grid_spacing: {problem}")
        return data

    @model_validator(mode="after")
    def _shape_keys(self):
        curved = self.shape != "plane"
        uses = {"radius": ("sphere", "cylinder"), "side": ("sphere", "cylinder"), "axis": ("cylinder",),
                "heightmap": ("heightmap",), "grid_spacing": ("heightmap",)}
        for key, shapes in uses.items():
            if self.shape in shapes and getattr(self, key) is None and key in ("radius", "heightmap", "grid_spacing"):
                raise ValueError(f"{key}: a {self.shape} needs its {key.replace('_', ' ')}"
                                 + (" (m)" if key != "heightmap" else " (a file of heights)"))
            if getattr(self, key) is not None and self.shape not in shapes:
                raise ValueError(f"{key}: not used by shape = {self.shape!r}"
                                 + (f"; set shape = {' or '.join(repr(s) for s in shapes)}" if not curved else ""))
        if self.heightmap is not None:
            read_height_grid(self.heightmap)
        if curved and self.point is not None:
            raise ValueError(f"point: a {self.shape} touches its tangent plane at trajectory.center; "
                             "leave point unset")
        if self.axis is not None:
            norm = math.sqrt(sum(x * x for x in self.axis))
            if abs(norm - 1.0) > 1e-6:       # as normal (review 46: [0, 2, 0] and [0, 0.001, 0] ran as [0, 1, 0])
                raise ValueError(f"axis: must be a unit vector (|a| = 1 within 1e-6), got |a| = {norm:.9g}")
            if self.normal is not None and abs(sum(a * b for a, b in zip(self.axis, self.normal))) > 1e-6 * norm:
                raise ValueError("axis: must be perpendicular to normal (the axis lies in the tangent plane)")
        return self

    def unit_notes(self) -> list[str]:
        """Valid values that read like a unit mistake, one line each for the
        command line to print: a sphere's or cylinder's radius above
        :data:`LARGE_RADIUS` (review 46: 300 for 300 mm ran as a 300 m part,
        nearly its tangent plane, and quoted the plane's limit, 4.5 % above
        the 0.3 m part's); a height map steeper than :data:`STEEP_MAP`
        between neighbouring points (review 65: a plate warped 0.1 mm, its
        heights written in millimetres, ran as a 15 cm deep bowl)."""
        notes = [note] if (note := large_radius_note(self.radius)) else []
        if self.heightmap is not None and (note := steep_map_note(self.heightmap, self.grid_spacing)):
            notes.append(note)
        return notes

    @model_validator(mode="after")
    def _unit_normal(self):
        if self.normal is not None:
            norm = math.sqrt(sum(x * x for x in self.normal))
            if abs(norm - 1.0) > 1e-6:
                raise ValueError(f"normal: must be a unit vector (|n| = 1 within 1e-6), got |n| = {norm:.9g}")
            if "tilt_deg" in self.model_fields_set:   # the shorthand given too: it must be the same plane
                t = math.radians(self.tilt_deg)
                if max(abs(a - b) for a, b in zip((math.sin(t), 0.0, -math.cos(t)), self.normal)) > 1e-6:
                    raise ValueError(f"tilt_deg: {self.tilt_deg:g} deg is not the plane of normal "
                                     f"{list(self.normal)}, which sets the plane; change normal, or drop tilt_deg")
        return self
