"""Speed for accuracy: measured fidelity profiles per scene (``gaitforge fidelity``).

Modules: ``grid`` (profiles swept), ``held`` (the contact-free pelvis-held variant and its
seeded rollouts), ``reference`` (the converged reference), ``task`` (task-level statistics
over seeds), ``stress`` (stability at the extremes, bisection), ``model_error`` (simulator,
tendon and pruning differences), ``sweep`` (the sweep and its recommendation), ``report``
(CSV, JSON, Pareto plot), ``store`` (saved profiles that scenes name). This package file
imports nothing: the scene loader reaches ``store`` without pulling the simulators in.
"""
