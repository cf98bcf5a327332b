"""The scene's MuJoCo modelling options: how MuJoCo's contact, joint limits and muscles are
made, nearer OpenSim's or its own (OpenSim ignores them all). Each is a field of
``workers.scenes.spec.Scene``; its type here carries its bounds and its documentation."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

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
ContactModel = Annotated[
    Literal["mujoco", "hunt-crossley"],
    Field(
        description="MuJoCo: the contact spheres' floor contact, MuJoCo's soft constraint or "
        "'hunt-crossley': OpenSim's law (Simbody's HuntCrossleyForce with the body's contact "
        "parameters: a Hertz force growing with depth^1.5, its dissipation and its friction "
        "against slip), applied as forces every MuJoCo step (workers.sim.hunt_crossley); "
        "obstacles keep MuJoCo's contact, and contact_timeconst_s and contact_solimp apply "
        "only to them. Body files only (OpenSim: ignored)",
    ),
]
JointLimits = Annotated[
    Literal["mujoco", "opensim"],
    Field(
        description="MuJoCo: how kept dofs with a body-file passive limit are held past it, "
        "MuJoCo's joint-limit constraint or 'opensim': OpenSim's CoordinateLimitForce spring "
        "(stiffness ramping up over the limit's transition, with damping; "
        "workers.sim.limit_springs), applied as forces every MuJoCo step. gait2d's knee goes "
        "past its 10-degree limit on OpenSim while walking; MuJoCo's constraint stops it. "
        "Body files only (OpenSim: ignored)",
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
    Literal["mujoco", "millard", "opensim"],
    Field(
        description="MuJoCo: its muscles' active force-length and force-velocity curves, "
        "MuJoCo's own or 'millard': lmin, lmax, vmax and fvmax fitted to Millard 2012's "
        "(OpenSim's muscle; the constants in workers.sim.muscle_curves), RMS 0.05 of "
        "isometric force off it where MuJoCo's own are 0.15 (length) and 0.14 (velocity) "
        "off, or 'opensim': no fit, Millard's own curves, with the fibre's pennation, "
        "applied as forces every MuJoCo step (workers.sim.opensim_muscles; body files only) "
        "(OpenSim: ignored)",
    ),
]
MusclePassive = Annotated[
    Literal["gait", "thelen", "thelen-fibre", "opensim"],
    Field(
        description="MuJoCo, body files only: its muscles' passive force-length curve fitted "
        "to Thelen 2003's (OpenSim's and the reference's) over the first 0.6 of its strain, "
        "'gait' (lmax shared with the active curve; softer beyond: gait2d's gastrocnemius "
        "at 1.6 optimal length 0.44 of peak force against Thelen's 1.0), 'thelen': lmax "
        "and fpmax of the passive force fitted over the whole strain (0.77 there), "
        "'thelen-fibre': that fit to Thelen's curve of the pennated fibre's own length, "
        "projected on the tendon, as OpenSim's rigid-tendon muscle pulls (MuJoCo's muscle "
        "has no pennation: its normalised length runs ahead of the fibre's past optimal "
        "length, gait2d's standing gastrocnemius 1.458 against 1.425), or 'opensim': no fit, "
        "OpenSim's own passive fibre force (its curve, pennation and fibre damping) applied "
        "as forces every MuJoCo step (workers.sim.opensim_muscles) (OpenSim: ignored)",
    ),
]
