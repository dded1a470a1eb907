"""The base of every settings model: a scenario's sections and a law's parameters.

Frozen, no unknown keys, and a :meth:`Settings.model_copy` that validates: pydantic's own
``model_copy(update=...)`` does not (review 58: a controller copied with ``f_d = -5`` N ran four
segments against -5 N, a two-value ``impedance.m`` failed deep inside NumPy). A copy with
``update`` is built like a new model from the fields set plus ``update``, so every check runs; its
error is one line naming the field (the class's :attr:`Settings.copy_error`).
"""
from __future__ import annotations

from typing import ClassVar

from pydantic import BaseModel, ConfigDict, ValidationError

__all__ = ["Settings"]


class Settings(BaseModel):
    """A frozen pydantic model that refuses unknown keys and validates its copies."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    copy_error: ClassVar[type[ValueError]] = ValueError
    """The error :meth:`model_copy` raises for a value the model refuses."""

    def model_copy(self, *, update: dict | None = None, deep: bool = False):
        """A copy; with ``update``, the fields it names replaced and the whole
        model validated again (``deep`` as pydantic's for a plain copy)."""
        if not update:
            return super().model_copy(deep=deep)
        # the fields set, each dumped whole (a nested tagged table keeps its kind: exclude_unset would drop a
        # default kind and turn an RLS law's copy into the TMT law), then the update
        whole = self.model_dump()
        data = {**{k: whole[k] for k in self.model_fields_set if k in whole}, **update}
        try:
            return type(self).model_validate(data)
        except ValidationError as exc:
            err = exc.errors()[0]
            loc = list(err["loc"])
            msg = err["msg"]
            if loc and isinstance(loc[-1], int) and err["type"] in ("missing", "too_short", "too_long"):
                loc, msg = loc[:-1], "wrong number of values"     # a list's length, not its item
                err = {**err, "input": data.get(loc[0]) if len(loc) == 1 else err.get("input")}
            if err["type"] == "value_error":     # a check of the model's own: "field: problem", as it words it
                field, _, rest = str((err.get("ctx") or {}).get("error", msg)).partition(": ")
                raise self.copy_error(f"{'.'.join(str(p) for p in (*loc, field))}: {rest}" if rest else
                                      f"{'.'.join(map(str, loc)) or type(self).__name__}: {field}") from None
            key = ".".join(str(p) for p in loc) or type(self).__name__
            got = f", got {err['input']!r}" if "input" in err and not isinstance(err["input"], dict) else ""
            raise self.copy_error(f"{key}: {msg}{got}") from None
