"""The operations behind the ``gaitforge`` CLI and the REST service, as functions with typed
inputs and results (pydantic models; ``model_dump(mode="json")`` or the report's
``to_dict()`` for JSON). They never print and never exit: bad input raises ``SpecError``
(a bad scene or job file, naming the file and the field), :class:`InputError` (a bad
argument, naming it), or for evaluation ``EvaluationError``/``CheckpointError``, each with a
one-line message.

- :mod:`.scenes`: list the catalogue, show a scene's compile report, check scenes with
  random excitations;
- :mod:`.train`: load a job with overrides and budget scaling, train (stoppable between
  iterations), one-line status reports;
- :mod:`.evaluate`: evaluate a checkpoint, with the speed-against-safety sweep;
- :mod:`.fidelity`: the fidelity sweep and its recommendation, and the stress test;
- :mod:`.bodies`: list the bodies, import an OpenSim model (with MuJoCo's stand-ins fitted).

Heavy libraries (torch, MuJoCo, OpenSim, Ray) load only when an operation runs.
"""

from gaitforge.service.ops.errors import InputError, validate_request
from gaitforge.workers.spec_io import SpecError

__all__ = ["InputError", "SpecError", "validate_request"]
