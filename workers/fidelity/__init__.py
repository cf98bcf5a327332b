"""Speed for accuracy: measured fidelity profiles per scene (``gaitforge fidelity``).

Modules: ``grid`` (profiles swept), ``held`` (the contact-free pelvis-held variant and its
seeded rollouts), ``reference`` (the converged reference), ``task`` (task-level statistics
over seeds), ``stress`` (stability at the extremes, bisection), ``model_error`` (simulator,
tendon and pruning differences), ``sweep`` (the sweep and its recommendation, saved through
``workers.scenes.saved_profiles``), ``report`` (CSV, JSON, Pareto plot). This package file
imports nothing.
"""
