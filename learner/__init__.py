"""The learner: PPO through a job's curriculum of stages (``trainer``, its state in
``run_state`` and hooks in ``hooks``, ``job``, ``curriculum``), policy blending at
stage transitions (``policy``, ``transitions``), mirror symmetry
and checkpoints. Evaluation, recordings, videos and shipping are the ``evaluation``
sub-package. ``workers`` never imports this package.
"""
