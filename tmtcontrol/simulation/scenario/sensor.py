"""The ``[sensor]`` and ``[simulation]`` sections: the force sensor (noise, filter) and the plant's integrator."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, StrictInt

from .fields import Section, num

__all__ = ["filter_pole", "SensorSettings", "SimulationSettings"]


def filter_pole(cutoff: float, Ts: float) -> float:
    """The discrete pole ``exp(-2 pi f_c Ts)`` of a first-order low-pass at
    ``cutoff`` Hz sampled every ``Ts`` s; 0 (no filter) for a cut-off of 0."""
    return float(math.exp(-2 * math.pi * cutoff * Ts)) if cutoff > 0 else 0.0


class SensorSettings(Section):
    """Force sensor along the normal."""
    noise_std: float = num(0.0, "N", "Gaussian noise, 1 sigma", ge=0, le=1e4)
    seed: StrictInt = Field(0, ge=0, description="seed of the noise generator (an integer)")
    filter_cutoff: float = num(0.0, "Hz", "first-order low-pass cut-off, below the Nyquist frequency "
                               "controller.rate/2; 0 = off", ge=0)

    def pole(self, Ts: float) -> float:
        """The force filter's discrete pole at control period ``Ts`` (0: no filter)."""
        return filter_pole(self.filter_cutoff, Ts)


BUILTIN_ONLY = ("integrator", "substeps", "contact_refine", "tol")
"""The ``[simulation]`` keys only the built-in plant reads."""


class SimulationSettings(Section):
    """Integrator: ``fixed`` (compiled RK4, ``substeps`` per control period,
    ``contact_refine`` times more in a period where the contact force
    switches on or off) or ``cvodes`` (adaptive, accuracy reference,
    tolerance ``tol``)."""
    integrator: Literal["fixed", "cvodes"] = Field("fixed", description="'fixed' (compiled RK4) or 'cvodes'")
    substeps: StrictInt = Field(1, ge=1, le=1000, description="RK4 steps per control period (fixed)")
    contact_refine: StrictInt = Field(4, ge=1, le=64, description=(
        "RK4 steps per substep in a period where the contact force switches on or off (fixed; 1: off)"))
    # below 1e-14 CVODES stops at once ("too much accuracy requested": double precision's limit)
    tol: float = num(1e-10, "1", "relative and absolute tolerance (cvodes)", ge=1e-14, le=1e-2)
    mujoco_contact: Literal["spring", "contact"] = Field("spring", description=(
        "with --plant mujoco: the ideal k_e spring along the normal (spring) or MuJoCo's own soft contact "
        "calibrated to k_e (contact; docs/mujoco.md)"))
    mujoco_friction: float = num(0.0, "1", "with --plant mujoco and mujoco_contact = contact: the Coulomb "
                                 "friction coefficient of MuJoCo's contact (0: frictionless)", ge=0, le=2.0)

    def mujoco_only(self) -> list[str]:
        """The settings given away from their defaults that only the MuJoCo
        plant reads (``key = value``): the built-in plant ignores them
        (review 33: friction 0.3 on the built-in plant ran frictionless, and
        nothing said so)."""
        return self._set(("mujoco_contact", "mujoco_friction"))

    def builtin_only(self) -> list[str]:
        """The settings given away from their defaults that only the built-in
        plant reads (``key = value``): the MuJoCo plant integrates with its
        own RK4 and ignores them (review 61: ``simulation.integrator =
        "cvodes"`` on ``--plant mujoco`` ran silently, where the flag
        ``--integrator`` is refused)."""
        return self._set(BUILTIN_ONLY)

    def on_mujoco(self) -> "SimulationSettings":
        """These settings as the MuJoCo plant runs them: the :meth:`builtin_only`
        keys at their defaults, so that a run on MuJoCo, its summary and the
        stiffness limit its verdicts quote are those of the same run without
        them (the limit models the built-in loop and read them: a UR5 run with
        ``substeps = 7`` computed a second deciding limit, 205 s, for a run
        that never used it)."""
        return self.model_copy(update={k: type(self).model_fields[k].default for k in BUILTIN_ONLY})

    def _set(self, keys) -> list[str]:
        return [f"simulation.{k} = {getattr(self, k)!r}" for k in keys
                if getattr(self, k) != type(self).model_fields[k].default]
