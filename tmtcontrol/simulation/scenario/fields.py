"""The scenario's building blocks: its error, number fields with units, the section base and tagged tables.

Every section of a scenario (:mod:`.robot`, :mod:`.environment`, ...) is a
frozen pydantic model that forbids unknown keys (:class:`Section`); every
number is finite, strict (a string is not a number) and carries its SI unit
(:func:`num`). A tagged table (the stiffness profile, the law, the damping
schedule) takes ``"name"`` for ``{kind = "name"}`` (:func:`tagged`).
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar

from pydantic import BeforeValidator, Field

from ...settings import Settings

__all__ = ["ScenarioError", "num", "F", "Pos", "NonNeg", "Stiff", "MAX_STIFFNESS", "MIN_PERIODS", "Section",
           "tagged", "tag_default"]


class ScenarioError(ValueError):
    """Invalid scenario input; the message names the key and the problem."""


def num(default, unit: str, doc: str, **limits) -> Any:
    """A finite number field (an integer is accepted) with its unit."""
    return Field(default, description=f"{doc} [{unit}]", allow_inf_nan=False, strict=True,
                 json_schema_extra={"unit": unit}, **limits)


F = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Pos = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
NonNeg = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0)]

MAX_STIFFNESS = 1e10
"""The stiffest environment a scenario (or ``analyze``/``design``) takes, N/m:
far stiffer than any contact a force-controlled arm meets (steel on steel at
these scales is about 1e8-1e9 N/m); above it the analysis' numbers overflow."""

MIN_PERIODS = 10
"""A path period, a stiffness segment and a stiffness sinusoid's period are at
least this many control periods (fewer samples cannot resolve them)."""

MIN_STIFFNESS = 1e-3
"""The smallest stiffness a profile may give, N/m (any form: values, knots, a table's rows)."""

Stiff = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=MIN_STIFFNESS, le=MAX_STIFFNESS)]


class Section(Settings):
    """A scenario's section: frozen, no unknown keys, its copies validated
    (:class:`~tmtcontrol.settings.Settings`), a refused copy a :class:`ScenarioError`."""

    copy_error: ClassVar[type[ValueError]] = ScenarioError


def tagged(value, default: str | None = None):
    """``"name"`` is shorthand for ``{kind = "name"}`` in a tagged union; a
    table without ``kind`` is of the union's default kind."""
    if isinstance(value, str):
        return {"kind": value}
    if isinstance(value, dict) and "kind" not in value and default is not None:
        return {"kind": default, **value}
    return value


def tag_default(default: str):
    return BeforeValidator(lambda v: tagged(v, default))
