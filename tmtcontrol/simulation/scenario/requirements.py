"""The ``[requirements]`` section: the user's bounds on the design, judged only where stated.

The paper claims stability and f_e -> f_d; anything beyond (how far the first
contact may overshoot, ...) is the user's requirement, not the toolkit's. A
bound left unset is not a verdict: the report shows the quantity as
information and names the bound it would be judged against once stated.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from .fields import Section

__all__ = ["RequirementsSettings"]

_Percent = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0, le=1000)]


class RequirementsSettings(Section):
    """The user's requirements (each optional: unset, not judged)."""
    first_contact_overshoot: _Percent | None = Field(None, description=(
        "largest first-contact overshoot of the 1-D sampled loop over the stiffness range, in percent of f_d: "
        "the damping design's bound and, when set, a verdict of the report on the scenario's own damping; "
        "unset, the design aims at 5 % (stability.design.DESIGN_OVERSHOOT) and nothing is judged [%]"),
        json_schema_extra={"unit": "%"})
