"""A scene's backend options: how MuJoCo models contact and muscles, nearer OpenSim's or its
own (``mujoco:``, OpenSim ignores them all), and OpenSim's tendons and run bounds
(``opensim:``, MuJoCo ignores them). Each type here carries its bounds and its
documentation.

Every option is set by a shipped scene option (``opensim-like``) or by a fidelity
measurement (``contact_timeconst_s``: the relaxed drop's contact softness;
``tendon``: the model-error check of compliant tendons; ``rebuild_every`` and
``step_wall_limit_s``: OpenSim's memory and a hung integrator)."""

from __future__ import annotations

from typing import Annotated, Literal

from gaitforge.workers.spec_types import SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field, model_validator

Timeconst = Annotated[float, Field(gt=0, le=1)]
Impedance = Annotated[float, Field(gt=0, lt=1)]
Width = Annotated[float, Field(gt=0, le=0.2)]
Power = Annotated[float, Field(ge=1, le=20)]

ContactTimeconst = Annotated[
    Timeconst | Annotated[tuple[Timeconst, Timeconst], Field(strict=False)] | None,
    Field(
        description="MuJoCo: the contacts' time constant (solref[0], s; larger is softer), or "
        "a [low, high] range drawn anew each episode; None keeps MuJoCo's 0.02 s. About 0.12 "
        "sinks gait2d's feet as deep as OpenSim's Hunt-Crossley spheres (OpenSim: ignored)",
    ),
]
ContactSolimp = Annotated[
    Annotated[tuple[Impedance, Impedance, Width, Impedance, Power], Field(strict=False)] | None,
    Field(
        description="MuJoCo: the contacts' impedance against penetration depth (solimp: "
        "[dmin, dmax, width m, midpoint, power]; dmin at the surface rising to dmax at width "
        "deep), so that a contact can stiffen with depth as a Hunt-Crossley sphere does; "
        "None keeps MuJoCo's [0.9, 0.95, 0.001, 0.5, 2] (OpenSim: ignored)",
    ),
]
MuscleMinActivation = Annotated[
    float,
    Field(
        ge=0.0,
        le=0.05,
        description="MuJoCo: the least activation its muscles keep (their excitations raised "
        "to it, their activation starting there); OpenSim's Millard muscle never goes below "
        "0.01, whose active force at rest (gait2d's vasti 1 % of 9594 N) holds a relaxed knee "
        "straight where MuJoCo's at 0 buckles; 0.01 matches it (OpenSim: ignored)",
    ),
]
MuscleCurves = Annotated[
    Literal["mujoco", "millard"],
    Field(
        description="MuJoCo: its muscles' active force-length and force-velocity curves, "
        "MuJoCo's own or 'millard': lmin, lmax, vmax and fvmax fitted to Millard 2012's "
        "(OpenSim's muscle; the constants in workers.sim.muscle_curves), RMS 0.05 of "
        "isometric force off it where MuJoCo's own are 0.15 (length) and 0.14 (velocity) "
        "off (OpenSim: ignored)",
    ),
]
MusclePassive = Annotated[
    Literal["gait", "thelen", "thelen-fibre"],
    Field(
        description="MuJoCo, body files only: its muscles' passive force-length curve fitted "
        "to Thelen 2003's (OpenSim's and the reference's) over the first 0.6 of its strain, "
        "'gait' (lmax shared with the active curve; softer beyond: gait2d's gastrocnemius "
        "at 1.6 optimal length 0.44 of peak force against Thelen's 1.0), 'thelen': lmax "
        "and fpmax of the passive force fitted over the whole strain (0.77 there), "
        "'thelen-fibre': that fit to Thelen's curve of the pennated fibre's own length, "
        "projected on the tendon, as OpenSim's rigid-tendon muscle pulls (MuJoCo's muscle "
        "has no pennation: its normalised length runs ahead of the fibre's past optimal "
        "length, gait2d's standing gastrocnemius 1.458 against 1.425) (OpenSim: ignored)",
    ),
]


class _Options(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)


class MujocoOptions(_Options):
    """How MuJoCo models what OpenSim models otherwise; each left out keeps MuJoCo's own."""

    contact_timeconst_s: ContactTimeconst = None
    contact_solimp: ContactSolimp = None
    muscle_min_activation: MuscleMinActivation = 0.0
    muscle_curves: MuscleCurves = "mujoco"
    muscle_passive: MusclePassive = "gait"

    @model_validator(mode="after")
    def _ranges(self) -> MujocoOptions:
        timeconst = self.contact_timeconst_s
        if isinstance(timeconst, tuple) and timeconst[0] > timeconst[1]:
            raise ValueError(f"contact_timeconst_s: low {timeconst[0]} > high {timeconst[1]}")
        if self.contact_solimp is not None and self.contact_solimp[0] > self.contact_solimp[1]:
            raise ValueError(
                f"contact_solimp: dmin {self.contact_solimp[0]} > dmax {self.contact_solimp[1]}"
            )
        return self


class OpenSimOptions(_Options):
    """OpenSim's tendons and the bounds of a run on it."""

    tendon: Literal["rigid", "compliant"] = Field(
        default="rigid", description="the muscles' tendons (MuJoCo's are always rigid)"
    )
    rebuild_every: Annotated[int, Field(ge=1, le=100_000)] = Field(
        default=100, description="episodes between model rebuilds (a bound on OpenSim's memory)"
    )
    step_wall_limit_s: Annotated[float, Field(gt=0, le=3600)] = Field(
        default=10.0,
        description="s of wall-clock time one control step may take (a hung integrator ends "
        "its episode, named)",
    )


MUJOCO_FIELDS = tuple(MujocoOptions.model_fields)
OPENSIM_FIELDS = tuple(OpenSimOptions.model_fields)
