"""Speed for accuracy: measured fidelity profiles per scene (``gaitforge fidelity``).

Modules: ``grid`` (profiles swept), ``held`` (the contact-free pelvis-held variant and its
seeded rollouts), ``reference`` (the converged reference), ``task`` (task-level statistics
over seeds), ``stress`` (stability at the extremes, bisection), ``model_error`` (simulator,
tendon and pruning differences), ``sweep`` (the sweep and its recommendation, saved through
``workers.scenes.saved_profiles``), ``report`` (CSV, JSON, Pareto plot). An imported body
against its OpenSim original (``gaitforge bodies compare``): ``conversion`` (the measures, with
``conversion_sweeps`` and ``conversion_drop``), ``conversion_sides`` (the two simulators),
``conversion_report`` and ``conversion_plot`` (the report); ``wrap_sides`` and
``conditional_wraps`` (MuJoCo's stand-ins fitted against the original). This package file
imports nothing.
"""
