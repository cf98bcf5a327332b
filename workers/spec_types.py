"""Value types that every spec shares (scenes, jobs, stages, requests): strict numbers, finite
floats, bounded names and the one seed type, so that a value a spec accepts is a value the
run can use, checked where it enters and not minutes later in a Ray actor.

A spec model takes :data:`SPEC_VALUES` into its ``model_config``: an int field then takes
only ints (no ``"1000"``, no ``true``), a float field ints and floats (no strings, no bools),
and neither infinity nor NaN; a string field only strings. YAML's and JSON's own numbers
still load. A tuple field (a range written as ``[low, high]``) must say
``Field(strict=False)`` to take the list that YAML and JSON give: its items stay strict.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import ConfigDict, Field

SPEC_VALUES = ConfigDict(strict=True, allow_inf_nan=False)
"""The ``model_config`` entries of a spec model: strict types, finite floats."""

SEED_LIMIT = 2**32
"""Seeds are below this: the tightest of numpy's legacy ``RandomState`` (``< 2**32``),
torch's ``manual_seed`` (``< 2**64``) and gymnasium's ``reset(seed=)`` (``>= 0``)."""

Seed = Annotated[
    int,
    Field(ge=0, lt=SEED_LIMIT, strict=True, description=f"an integer in [0, {SEED_LIMIT})"),
]
"""A random seed as a job, a stage or a command takes it: an int in ``[0, 2**32)``."""

MAX_NAME_LENGTH = 128
"""The longest name (a job's, a scene's, a stage's): names become folder and file names."""

Name = Annotated[
    str,
    Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", min_length=1, max_length=MAX_NAME_LENGTH),
]
"""A name that is safe as a file name: a letter or digit, then letters, digits, ``_.-``."""

MAX_REF_LENGTH = 1024
"""The longest reference to a file (a scene YAML path, a checkpoint directory, an address)."""

Ref = Annotated[str, Field(min_length=1, max_length=MAX_REF_LENGTH)]
"""A catalogue name or a file path, as a spec names a scene or a checkpoint."""

MAX_TEXT_LENGTH = 4096
"""The longest free text (a scene's description)."""

__all__ = [
    "MAX_NAME_LENGTH",
    "MAX_REF_LENGTH",
    "MAX_TEXT_LENGTH",
    "SEED_LIMIT",
    "SPEC_VALUES",
    "Name",
    "Ref",
    "Seed",
]
