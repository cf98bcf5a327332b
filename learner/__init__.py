"""The learner: PPO through a job's curriculum of stages (``trainer``, ``job``,
``curriculum``), policy blending, cloning and fresh networks at stage transitions
(``policy``, ``distil``), mirror symmetry, checkpoints, evaluation and recordings.
``workers`` never imports this package.
"""
